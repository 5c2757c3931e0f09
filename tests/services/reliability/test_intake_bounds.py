"""The fusion intake and the recorder never crash on input, count every rejection under a
bounded vocabulary, and keep every buffer and counter bounded (docs/reliability.md §1)."""

from __future__ import annotations

import json
import logging

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from skyfuse.schemas import PlotBatch, RadarSite, keys
from skyfuse.services.fusion.service import FusionConfig, FusionCore
from skyfuse.services.recording.mcap_io import iter_recording
from skyfuse.services.recording.recorder import Recorder, RecorderConfig
from skyfuse.services.runtime.ratelimit import RateLimitedLog
from skyfuse.services.runtime.seen_batches import DUPLICATE, JUMP, TIME_JUMP
from skyfuse.services.runtime.transport import Received

T0 = 1_700_000_000_000_000_000


def batch(radar="R1", seq=0, n=2, scan=0, t=T0, **kw) -> dict:
    d = {
        "radar_id": radar,
        "scan": scan,
        "seq": seq,
        "time_start": t,
        "time_end": t + 1000,
        "time": [t + i for i in range(n)],
        "range": [10_000.0 + i for i in range(n)],
        "azimuth": [0.5] * n,
        "altitude": [3000.0] * n,
    }
    d.update(kw)
    return d


def site(rid: str) -> RadarSite:
    return RadarSite(radar_id=rid, lat=45.0, lon=20.0, kind="2d")


def core(**cfg) -> FusionCore:
    return FusionCore(FusionConfig(**cfg), pipeline_factory=lambda frame: None)


FIELDS = sorted(PlotBatch.model_fields)
SERVICE_REASONS = {
    "batch radar_id does not match its key",
    DUPLICATE,
    JUMP,
    TIME_JUMP,
    "out of sequence",
    "message too large",
    "too many plots in batch",
    "too many radars",
}
VOCAB = (
    {f"invalid PlotBatch: {f}" for f in FIELDS}
    | {f"invalid PlotBatch: {r}" for r in ("not JSON", "unknown field", "value", "undecodable")}
    | SERVICE_REASONS
)
hostile_values = (
    st.none()
    | st.integers()
    | st.floats()
    | st.text(max_size=6)
    | st.lists(st.integers() | st.floats() | st.none(), max_size=3)
)


@st.composite
def hostile(draw) -> bytes:
    d = batch(seq=draw(st.integers(0, 5)))
    key = draw(st.sampled_from([*FIELDS, draw(st.text(min_size=1, max_size=10))]))
    d[key] = draw(hostile_values)
    raw = json.dumps(d)
    return raw[: draw(st.integers(0, len(raw)))].encode() if draw(st.booleans()) else raw.encode()


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(hostile(), min_size=1, max_size=20))
def test_fusion_intake_counts_every_payload_and_reasons_stay_in_the_vocabulary(payloads):
    c = core()
    accepted = sum(
        c.on_plots_payload(keys.radar_plots("R1"), p, arrival=0.0) is not None for p in payloads
    )
    assert c.counters["batches_received"] == len(payloads)
    assert accepted == c.counters["batches_in"]
    assert accepted + sum(c.rejected.values()) == len(payloads)  # nothing silently lost
    assert set(c.rejected) <= VOCAB


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(hostile(), min_size=1, max_size=10))
def test_recorder_never_raises_and_counts(tmp_path_factory, payloads):
    out = tmp_path_factory.mktemp("rec") / "r.mcap"
    rec = Recorder(RecorderConfig(out=out, flush_interval=60))
    ok = sum(rec.handle(Received("data", keys.radar_plots("R1"), p, True, T0)) for p in payloads)
    rec.close()
    # a repeated valid batch is a counted duplicate, a number or time far beyond the
    # radar's last one a counted jump (services.runtime.seen_batches)
    assert set(rec.rejected) <= {"invalid PlotBatch", "duplicate batch", "sequence jump",
                                 "time jump"}  # fmt: skip
    assert ok + sum(rec.rejected.values()) == len(payloads)
    assert sum(1 for m in iter_recording(out) if m.topic == keys.radar_plots("R1")) == ok


def test_status_stays_bounded_under_hostile_input():
    c = core(max_radars=20)
    real = [f"R{k}" for k in range(5)]
    for rid in real:  # radars with sites are never crowded out
        c.on_site_payload(keys.radar_site(rid), site(rid).to_json_bytes())
    for i in range(3000):  # random field names, many radar ids, each id on its own key
        rid = f"X{i}"
        bad = json.dumps(batch(rid, **{f"f{i}]": 1})).encode()
        c.on_plots_payload(keys.radar_plots(rid), bad, 0)
        c.on_plots_payload(keys.radar_plots(rid), json.dumps(batch(rid, seq=i)).encode(), 0)
        c.on_alive(keys.radar_alive(f"Y{i}"), True)
    st_json = c.status().to_json_bytes()
    assert len(c.radars) == 20 and set(real) <= set(c.radars)
    assert len(st_json) < 10_000, len(st_json)
    assert set(c.rejected) == {"invalid PlotBatch: unknown field"}
    assert c.rejected["invalid PlotBatch: unknown field"] == 3000
    assert c.counters["radars_forgotten"] == 2 * 3000 - (20 - 5)
    # all 20 places held by radars with sites: a further id is refused and counted
    for k in range(5, 20):
        c.on_site_payload(keys.radar_site(f"R{k}"), site(f"R{k}").to_json_bytes())
    assert c.on_plots_payload(keys.radar_plots("Z"), json.dumps(batch("Z")).encode(), 0) is None
    assert c.rejected["too many radars"] == 1


def test_size_limits_are_configurable_and_counted():
    c = core(max_message_bytes=2_000, max_plots_per_batch=10)
    key = keys.radar_plots("R1")
    assert c.on_plots_payload(key, json.dumps(batch(n=10)).encode(), 0) is not None
    assert c.on_plots_payload(key, json.dumps(batch(seq=1, n=11)).encode(), 0) is None
    big = json.dumps(batch(seq=2, n=60)).encode()
    assert len(big) > 2_000
    assert c.on_plots_payload(key, big, 0) is None
    assert c.rejected == {"too many plots in batch": 1, "message too large": 1}


def test_rejection_log_is_rate_limited(caplog):
    t = [0.0]
    limited = RateLimitedLog(logging.getLogger("t.rl"), rate=2.0, burst=5, clock=lambda: t[0])
    with caplog.at_level(logging.WARNING, logger="t.rl"):
        for i in range(1000):  # 1000 novel messages within 1 s
            t[0] = i / 1000
            limited.warning("novel reason %d", i)
    lines = [r for r in caplog.records if r.name == "t.rl"]
    assert 5 <= len(lines) <= 5 + 2  # burst + rate × 1 s
    assert limited.suppressed_total == 1000 - len(lines)
    assert "suppressed" in lines[-1].getMessage()


def test_fusion_log_is_rate_limited(caplog):
    c = core()
    with caplog.at_level(logging.WARNING, logger="skyfuse.services.fusion.service"):
        for i in range(500):
            c.on_plots_payload(keys.radar_plots("R1"), b"{" + str(i).encode(), 0)
    assert c.rejected["invalid PlotBatch: not JSON"] == 500
    assert len(caplog.records) <= 12


def test_recorder_scan_buffer_is_bounded(tmp_path):
    cfg = RecorderConfig(out=tmp_path / "r.mcap", max_scan_plots=5_000, max_scan_radars=3)
    rec = Recorder(cfg)
    for rid in ("A", "B", "C", "D"):
        rec.handle(Received("data", keys.radar_site(rid), site(rid).to_json_bytes(), True, T0))
    peak = 0
    for seq in range(60):  # one radar, scan never changes: 60 000 plots
        p = json.dumps(batch("A", seq=seq, n=1000)).encode()
        assert rec.handle(Received("data", keys.radar_plots("A"), p, True, T0 + seq))
        peak = max(peak, rec._scan_count.get("A", 0))
    for rid in ("B", "C", "D"):
        p = json.dumps(batch(rid, n=10)).encode()
        assert rec.handle(Received("data", keys.radar_plots(rid), p, True, T0))
    rec.close()
    assert peak <= 5_000
    assert rec.limits["scan plots: written early"] == 60 // 5 - 1
    assert rec.limits["scan radars: plots not shown"] == 1
    fixes = [m for m in iter_recording(cfg.out, decode=False) if m.topic == "/foxglove/plots"]
    assert len(fixes) == 60 // 5 + 2  # 12 scans of A, then B and C at close
    plots = [m for m in iter_recording(cfg.out) if m.topic.startswith("skyfuse/@v1/radar/")]
    assert (
        sum(m.topic.endswith("/plots") for m in plots) == 63
    )  # every batch is in the MCAP whatever the display buffer did


def test_recorder_message_size_limit(tmp_path):
    rec = Recorder(RecorderConfig(out=tmp_path / "r.mcap", max_message_bytes=2_000))
    small, big = json.dumps(batch(n=10)).encode(), json.dumps(batch(seq=1, n=60)).encode()
    assert len(small) <= 2_000 < len(big)
    assert rec.handle(Received("data", keys.radar_plots("R1"), small, True, T0))
    assert not rec.handle(Received("data", keys.radar_plots("R1"), big, True, T0))
    rec.close()
    assert rec.rejected == {"message too large": 1} and rec.messages == 1
