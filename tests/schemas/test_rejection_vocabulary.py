"""Every payload decodes to a message or to a reason from the fixed vocabulary of
:mod:`schemas.rejection`, never to an exception: hypothesis over the whole payload space
(arbitrary JSON values in every field, unknown keys, out-of-range integers, raw bytes)."""

from __future__ import annotations

import json

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from skyfuse.schemas import PlotBatch, RadarSite, Truth
from skyfuse.schemas.rejection import decode, rejection_detail, rejection_reason

GOOD = {
    "radar_id": "R1",
    "scan": 3,
    "seq": 40,
    "time_start": 1_700_000_000_000_000_000,
    "time_end": 1_700_000_000_250_000_000,
    "time": [1_700_000_000_100_000_000, 1_700_000_000_200_000_000],
    "range": [10_000.0, 20_000.0],
    "azimuth": [0.5, 1.0],
    "altitude": [3000.0, None],
    "mode_s": [0xABCDEF, None],
}

json_scalars = (
    st.none()
    | st.booleans()
    | st.integers()  # unbounded: includes > int64 and < -int64
    | st.sampled_from([2**63, 2**64, -(2**63) - 1, 10**400, -(10**30)])
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=8)
)
json_values = st.recursive(
    json_scalars,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=5), inner),
    max_leaves=12,
)


def vocabulary(model) -> set[str]:
    n = model.__name__
    fixed = {f"invalid {n}: {r}" for r in ("not JSON", "unknown field", "value", "undecodable")}
    return fixed | {f"invalid {n}: {f}" for f in model.model_fields}


@st.composite
def mutated_batches(draw) -> bytes:
    d = json.loads(json.dumps(GOOD))
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["replace", "element", "unknown", "drop"]))
        key = draw(st.sampled_from(sorted(d) or ["time"]))
        if op == "replace":
            d[key] = draw(json_values)
        elif op == "element" and isinstance(d.get(key), list) and d[key]:
            d[key][draw(st.integers(0, len(d[key]) - 1))] = draw(json_values)
        elif op == "unknown":
            d[draw(st.text(min_size=1, max_size=12))] = draw(json_values)
        else:
            d.pop(key, None)
    text = json.dumps(d)
    if draw(st.booleans()) and len(text) > 2:  # truncate / corrupt some
        cut = draw(st.integers(0, len(text)))
        text = text[:cut]
    return text.encode()


@settings(max_examples=600, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_batches())
def test_any_plot_batch_payload_is_a_message_or_a_vocabulary_reason(payload):
    msg, exc = decode(PlotBatch, payload)
    if msg is None:
        assert rejection_reason(PlotBatch, exc) in vocabulary(PlotBatch)
        assert len(rejection_detail(exc)) <= 200
    else:  # accepted: every column fits the arrays the service builds
        for name in ("time", "target_id", "mode_s", "mode_3a", "range", "azimuth"):
            msg.column(name)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_raw_bytes_never_raise(payload):
    for model in (PlotBatch, RadarSite, Truth):
        msg, exc = decode(model, payload)
        assert msg is None
        assert rejection_reason(model, exc) in vocabulary(model)


def test_out_of_int64_time_is_a_rejection_of_field_time():
    # the OverflowError the time guards fixed: a plot time beyond int64 escaped validation
    for bad in (2**63, 2**64, -(2**63) - 1):
        _, exc = decode(PlotBatch, json.dumps({**GOOD, "time": [bad, bad]}))
        assert rejection_reason(PlotBatch, exc) == "invalid PlotBatch: time"
    _, exc = decode(PlotBatch, json.dumps({**GOOD, "target_id": [2**64, 1]}))
    assert rejection_reason(PlotBatch, exc) == "invalid PlotBatch: target_id"
    _, exc = decode(PlotBatch, json.dumps({**GOOD, "time_end": 2**63}))
    assert rejection_reason(PlotBatch, exc) == "invalid PlotBatch: time_end"
    # int64 max itself is valid
    top = 2**63 - 1
    ok = {**GOOD, "time_start": top, "time_end": top, "time": [top, top]}
    assert decode(PlotBatch, json.dumps(ok))[0] is not None


def test_reason_names_schema_fields_only():
    cases = {
        json.dumps({**GOOD, "sector_s]tart": 1.0}): "invalid PlotBatch: unknown field",
        json.dumps({**GOOD, "range": [-1.0, 5.0]}): "invalid PlotBatch: range",
        json.dumps({**GOOD, "range": [1.0]}): "invalid PlotBatch: range",  # unequal columns
        json.dumps({**GOOD, "radar_id": "a/b"}): "invalid PlotBatch: radar_id",
        '{"radar_id": "R1", ': "invalid PlotBatch: not JSON",
        "[1, 2]": "invalid PlotBatch: not JSON",
        "[" * 100_000: "invalid PlotBatch: not JSON",
        json.dumps({**GOOD, "x": [1.0, 2.0]}): "invalid PlotBatch: value",
    }
    for payload, reason in cases.items():
        msg, exc = decode(PlotBatch, payload)
        assert msg is None and rejection_reason(PlotBatch, exc) == reason, payload[:60]
    assert rejection_reason(PlotBatch, OverflowError("x")) == "invalid PlotBatch: undecodable"
