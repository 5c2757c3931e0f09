"""PlotBatch column checks and the column arrays kept by the validator.

The range checks take a min/max shortcut when every value is good; these tests compare
accept/reject and the exact message with a brute-force Python reference that walks the
values in order (first non-finite value, then the first below the bound, then the first
above it), over random columns with bad values planted at random places."""

from __future__ import annotations

import math

import numpy as np
import pytest
from skyfuse.schemas import PlotBatch
from skyfuse.schemas.columns import check_codes, check_range


def _reference(name, values, lo, hi, hi_open, allow_nan, unit):
    """The message the checks must give (None = accepted), by plain iteration."""
    vals = [math.nan if v is None else float(v) for v in values]
    for i, v in enumerate(vals):
        if math.isinf(v) or (math.isnan(v) and not allow_nan):
            what = "infinite" if allow_nan else "not finite (NaN or inf)"
            return f"{name}[{i}] = {v!r}: value is {what}"
    if lo is not None:
        for i, v in enumerate(vals):
            if v < lo:
                return f"{name}[{i}] = {v!r}: must be >= {lo} {unit}".rstrip()
    if hi is not None:
        for i, v in enumerate(vals):
            if (v >= hi) if hi_open else (v > hi):
                op = "<" if hi_open else "<="
                return f"{name}[{i}] = {v!r}: must be {op} {hi} {unit}".rstrip()
    return None


BOUNDS = [
    ("range", 0.0, None, False, False, "m"),
    ("azimuth", 0.0, 2 * math.pi, True, False, "rad"),
    ("elevation", -math.pi / 2, math.pi / 2, False, True, "rad"),
    ("altitude", -1000.0, 100000.0, False, True, "m"),
]


@pytest.mark.parametrize("bounds", BOUNDS, ids=[b[0] for b in BOUNDS])
def test_check_range_matches_brute_force(bounds):
    name, lo, hi, hi_open, allow_nan, unit = bounds
    rng = np.random.default_rng(7)
    span_hi = 1e6 if hi is None else hi
    specials = [math.inf, -math.inf, math.nan, None, lo - 1e-9, span_hi, -1.0, 2 * span_hi]
    n_reject = 0
    for trial in range(400):
        n = int(rng.integers(1, 40))
        values = list(rng.uniform(lo, span_hi * 0.999, n))
        for _ in range(int(rng.integers(0, 3))):  # 0, 1 or 2 planted values
            values[int(rng.integers(n))] = specials[int(rng.integers(len(specials)))]
        if not allow_nan and None in values:
            continue  # pydantic rejects null in these columns before the check
        if trial % 50 == 0 and allow_nan:
            values = [None] * n  # every value null: accepted
        expected = _reference(name, values, lo, hi, hi_open, allow_nan, unit)
        if expected is None:
            arr = check_range(name, values, lo, hi, hi_open=hi_open, allow_nan=allow_nan, unit=unit)
            ref = np.array([math.nan if v is None else v for v in values])
            np.testing.assert_array_equal(arr, ref)
        else:
            n_reject += 1
            with pytest.raises(ValueError) as e:
                check_range(name, values, lo, hi, hi_open=hi_open, allow_nan=allow_nan, unit=unit)
            assert str(e.value) == expected
    assert n_reject > 50  # the planted values did reach the slow path


def test_check_codes_names_the_first_bad_code():
    check_codes("mode_3a", [None, 0, 4095, None], 0o7777)
    check_codes("mode_3a", [None, None], 0o7777)
    with pytest.raises(ValueError, match=r"^mode_3a\[2\] = 4096: must be in 0..4095$"):
        check_codes("mode_3a", [1, None, 4096, -1], 0o7777)
    with pytest.raises(ValueError, match=r"^mode_s\[1\] = -1: must be in 0..16777215$"):
        check_codes("mode_s", [None, -1, 2**24], 0xFFFFFF)


def _batch(**cols) -> PlotBatch:
    base = {"radar_id": "r1", "scan": 0, "seq": 0, "time_start": 0, "time_end": 10}
    return PlotBatch.model_validate({**base, **cols})


def test_columns_kept_read_only_and_rebuilt_after_a_change():
    b = _batch(time=[1, 2, 3], range=[10.0, 20.0, 30.0], azimuth=[0.1, 0.2, 0.3])
    r = b.column("range")
    assert r is b.column("range")  # built once
    assert not r.flags.writeable
    with pytest.raises(ValueError):
        r[0] = 0.0
    c = b.model_copy(update={"range": [5.0, 6.0, 7.0]})
    np.testing.assert_array_equal(c.column("range"), [5.0, 6.0, 7.0])
    np.testing.assert_array_equal(b.column("range"), [10.0, 20.0, 30.0])
    b.range = [1.0, 2.0, 3.0]  # assignment (validate_assignment is off): a new list
    np.testing.assert_array_equal(b.column("range"), [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(b.column("time"), [1, 2, 3])
    assert b.column("time").dtype == np.int64


def test_kept_arrays_do_not_change_equality_or_json():
    b = _batch(time=[1, 2], range=[10.0, 20.0], azimuth=[0.1, 0.2], mode_s=[None, 5])
    same = PlotBatch.model_construct(**dict(b))  # no validation: no kept arrays
    assert b == same and same == b
    np.testing.assert_array_equal(same.column("mode_s"), [-1, 5])
    assert PlotBatch.from_json_bytes(b.to_json_bytes()) == b
    assert b != b.model_copy(update={"range": [10.0, 21.0]})


def test_time_checks_keep_their_messages():
    with pytest.raises(ValueError, match=r"time\[2\] = 1 is earlier than time\[1\] = 5"):
        _batch(time=[0, 5, 1], range=[1.0, 1.0, 1.0], azimuth=[0.0, 0.0, 0.0])
    assert len(_batch(time=[3, 3, 3], range=[1.0] * 3, azimuth=[0.0] * 3)) == 3
