"""Superseded by ``benchmarks/scaling.py`` (same planar steady-state setup, plus ``gnn``,
2,000 targets, 10,000 clutter plots, peak memory, a stage profile and a log–log plot).

    python benchmarks/tracker_scaling.py [--quick]   # runs benchmarks/scaling.py
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from scaling import main

if __name__ == "__main__":
    raise SystemExit(main())
