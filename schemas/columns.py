"""Validation of columnar arrays carried in wire messages.

Every check names the field, the offending index and value, and the reason, so a
rejected message can be reported precisely ("range[17] = -3.0: must be >= 0 m").
Checks run in NumPy so a 500-plot batch validates in microseconds.
"""

from __future__ import annotations

import math
import re

import numpy as np

TWO_PI = 2.0 * math.pi


def as_float_array(
    name: str, values: list[float] | list[float | None], *, allow_nan: bool = False
) -> np.ndarray:
    """Return ``values`` as float64 and reject inf (and NaN unless ``allow_nan``).

    ``None`` entries (JSON null, "not measured") become NaN and need ``allow_nan``."""
    arr = np.asarray(values, dtype=np.float64)
    bad = np.isinf(arr) if allow_nan else ~np.isfinite(arr)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        what = "infinite" if allow_nan else "not finite (NaN or inf)"
        raise ValueError(f"{name}[{i}] = {float(arr[i])!r}: value is {what}")
    return arr


def check_range(
    name: str,
    values: list[float],
    lo: float | None = None,
    hi: float | None = None,
    *,
    hi_open: bool = False,
    allow_nan: bool = False,
    unit: str = "",
) -> np.ndarray:
    """Reject values outside ``[lo, hi]`` (or ``[lo, hi)`` with ``hi_open``); return the
    values as float64 (None → NaN). Values in range take two reductions (their minimum
    and maximum, NaN ignored with ``allow_nan``); only a batch with a bad value goes
    through the checks that name the first offending index."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.size and _within(arr, lo, hi, hi_open, allow_nan):
        return arr
    as_float_array(name, values, allow_nan=allow_nan)
    with np.errstate(invalid="ignore"):
        if lo is not None:
            bad = arr < lo
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                msg = f"{name}[{i}] = {float(arr[i])!r}: must be >= {lo} {unit}"
                raise ValueError(msg.rstrip())
        if hi is not None:
            bad = arr >= hi if hi_open else arr > hi
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                op = "<" if hi_open else "<="
                msg = f"{name}[{i}] = {float(arr[i])!r}: must be {op} {hi} {unit}"
                raise ValueError(msg.rstrip())
    return arr


def _within(arr: np.ndarray, lo, hi, hi_open: bool, allow_nan: bool) -> bool:
    """Whether every value is finite (or NaN with ``allow_nan``) and within the bounds:
    min and max (``fmin``/``fmax`` skip NaN; a NaN min/max, or ±inf, fails a bound;
    compared as Python floats, cheaper than NumPy scalars)."""
    low = float(np.fmin.reduce(arr) if allow_nan else arr.min())
    high = float(np.fmax.reduce(arr) if allow_nan else arr.max())
    if low != low:  # NaN: every value null (allow_nan), or a NaN present (not allowed)
        return allow_nan and bool(np.isnan(arr).all())
    if not (low >= lo if lo is not None else low > -math.inf):
        return False
    if hi is None:
        return high < math.inf
    return high < hi if hi_open else high <= hi


def check_nullable_range(
    name: str, values: list[float | None], lo: float, hi: float, *, hi_open: bool, unit: str
) -> None:
    """Reject values of a nullable float column outside ``[lo, hi]`` (``[lo, hi)`` with
    ``hi_open``), for columns whose non-finite values the model has already rejected:
    the minimum and maximum of the values present in plain Python (for the short columns
    of a sector, 3-10 times cheaper than arrays); a bad value goes to :func:`check_range`
    for the message naming it."""
    present = [v for v in values if v is not None]
    if present:
        low, high = min(present), max(present)
        if low < lo or (high >= hi if hi_open else high > hi):
            check_range(name, values, lo, hi, hi_open=hi_open, allow_nan=True, unit=unit)


def check_codes(name: str, values: list[int | None], hi: int) -> None:
    """Reject integer codes outside ``0..hi`` (None = no code; Mode-S addresses,
    Mode-3/A codes): the minimum and maximum of the codes present, then, only when one
    is out of range, the search for the first offending index."""
    present = [v for v in values if v is not None]
    if present and not (0 <= min(present) and max(present) <= hi):
        for i, v in enumerate(values):
            if v is not None and not 0 <= v <= hi:
                raise ValueError(f"{name}[{i}] = {v}: must be in 0..{hi}")


def check_strings(name: str, values: list[str | None], pattern: re.Pattern, what: str) -> None:
    """Reject strings (None = absent) that do not match ``pattern`` (``what`` says what
    they must be); the message names the first offending index and value (its first 20
    characters)."""
    match = pattern.match
    if all(v is None or match(v) for v in values):
        return
    for i, v in enumerate(values):
        if v is not None and not match(v):
            raise ValueError(f"{name}[{i}] = {v[:20]!r}: must be {what}")


def check_non_decreasing(name: str, values: list[int]) -> None:
    """Reject a time column that goes backwards."""
    if len(values) < 2:
        return
    arr = np.asarray(values, dtype=np.int64)
    back = np.diff(arr) < 0
    if back.any():
        i = int(np.flatnonzero(back)[0]) + 1
        raise ValueError(
            f"{name}[{i}] = {int(arr[i])} is earlier than {name}[{i - 1}] = {int(arr[i - 1])}:"
            " times must be in non-decreasing order"
        )


def check_equal_lengths(columns: dict[str, list | None]) -> int:
    """Return the common length of the present columns or name the mismatch."""
    lengths = {k: len(v) for k, v in columns.items() if v is not None}
    if not lengths:
        return 0
    ref_name, ref_len = next(iter(lengths.items()))
    for k, n in lengths.items():
        if n != ref_len:
            raise ValueError(
                f"column {k!r} has {n} values but {ref_name!r} has {ref_len}:"
                " all columns must have one value per plot"
            )
    return ref_len
