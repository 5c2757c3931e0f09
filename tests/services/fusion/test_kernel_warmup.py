"""The kernel warm-up (:mod:`fusion.tracker.kernel_warmup`) loads every compiled kernel
the tracker calls: in a fresh process, after ``warm_up()``, tracking the sample
recording (several radars, out-of-sequence updates, IMM and CV) compiles nothing more —
no numba dispatcher of ``fusion`` gains a signature — so the live service's first
batches do not pay the compilation."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

SAMPLE = Path(__file__).resolve().parents[3] / "recordings" / "regional-demo.mcap"

SCRIPT = r"""
import importlib, json, pkgutil, sys
import numba.core.registry
import skyfuse.fusion as fusion
from skyfuse.fusion.tracker.kernel_warmup import warm_up
from skyfuse.services.cli.main import main as skyfuse_main

def dispatchers():
    found = {}
    for m in pkgutil.walk_packages(fusion.__path__, "skyfuse.fusion."):
        mod = importlib.import_module(m.name)
        for name, obj in vars(mod).items():
            if isinstance(obj, numba.core.registry.CPUDispatcher):
                found[f"{obj.py_func.__module__}.{obj.__name__}"] = obj
    return found

def signatures():
    return {k: sorted(map(str, d.signatures)) for k, d in dispatchers().items()}

before = signatures()
warm_up()
warmed = signatures()
rec, out = sys.argv[1], sys.argv[2]
for motion in ("imm-cv-ct", "cv"):
    assert skyfuse_main(["track", rec, "--out", out, "--no-progress", "--motion", motion]) == 0
after = signatures()
print(json.dumps({"before": before, "warmed": warmed, "after": after}))
"""


@pytest.mark.skipif(not SAMPLE.exists(), reason="sample recording absent")
def test_after_warm_up_tracking_compiles_no_kernel(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(SAMPLE), str(tmp_path / "o.mcap")],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["before"] and not any(got["before"].values())  # a fresh process
    used = {k for k, v in got["after"].items() if v}
    assert used, "the tracking run called no compiled kernel"
    assert got["after"] == got["warmed"]  # nothing compiled while tracking
