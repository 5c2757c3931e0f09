"""Number formatting of the JSON summaries of ``skyfuse track``, ``skyfuse eval`` and
the demo's report: one rounding rule and one way to fold rejection reasons.

:func:`json_number` rounds to a fixed number of decimals and maps NaN/±inf (a metric with
no sample) to ``None`` (JSON ``null``), so every summary writes "no value" the same way.
"""

from __future__ import annotations

import math
import re
from collections import Counter

_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")

DIGITS = 4
"""Default decimals of a summary figure."""


def json_number(v, digits: int = DIGITS) -> float | None:
    """``v`` rounded to ``digits`` decimals; ``None`` for ``None``, NaN or ±inf."""
    if v is None:
        return None
    v = float(v)
    return round(v, digits) if math.isfinite(v) else None


def rejection_reasons(rejected: dict[str, int]) -> dict[str, int]:
    """Rejection counts with the numbers of each reason replaced by ``#`` (one key per
    kind of reason, not per value)."""
    out: Counter = Counter()
    for reason, n in rejected.items():
        out[_NUMBER.sub("#", reason)] += n
    return dict(out)
