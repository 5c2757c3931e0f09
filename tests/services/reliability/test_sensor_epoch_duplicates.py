"""Duplicates by ``(radar, epoch, seq)`` (``services.runtime.seen_batches``).

* A ``skyfuse sensor --asterix FILE`` started again publishes its whole file again with
  the same epoch (a fingerprint of the file): a ``skyfuse fusion`` and a ``skyfuse
  record`` process next to it refuse every repeat as ``duplicate batch`` — the
  recording holds each batch once, the fusion service applies none twice. The file has
  more than 256 batches per radar: the earlier "last 256 batches" memory stored the
  older ones again.
* :class:`SeenBatches` against a brute-force reference (the set of every identity ever
  added) on hypothesis streams: increasing numbers with bounded reordering, repeats of
  any earlier batch, several epochs; epoch 0 (not announced) keeps the old rule.
"""

from __future__ import annotations

import json
import signal

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from service_support import last_payload
from skyfuse.schemas import PlotBatch, Status, keys
from skyfuse.services.recording.mcap_io import iter_recording
from skyfuse.services.runtime.seen_batches import LEGACY_RECENT, SeenBatches
from skyfuse.services.runtime.transport import (
    Inbox,
    TransportConfig,
    free_port,
    open_session,
    service_alive_key,
    wait_for_tokens,
)


@pytest.mark.service
def test_a_file_published_again_is_refused_as_duplicates(start_skyfuse, tmp_path, until):
    pcap = tmp_path / "r.pcap"
    sim = start_skyfuse(
        "simulate", "--scenario", "regional", "--param", "radars=3", "--targets", "10",
        "--duration", "130", "--format", "asterix", "--out", str(pcap), log="simulate",
    )  # fmt: skip
    assert sim.wait(timeout=120) == 0
    ep = f"tcp/127.0.0.1:{free_port()}"
    out, stats = tmp_path / "r.mcap", tmp_path / "stats.json"
    sensor = ("sensor", "--asterix", str(pcap), "--sites", f"{pcap}.sites.toml",
              "--speed", "40", "--connect", ep)  # fmt: skip
    with open_session(TransportConfig(listen=[ep])) as s:
        status = Inbox()
        status.subscribe(s, keys.fusion_status("main"), "status")
        rec = start_skyfuse("record", "--out", str(out), "--connect", ep, "--stats", str(stats),
                            log="recorder")  # fmt: skip
        fusion = start_skyfuse(
            "fusion", "--connect", ep, "--future-tolerance", "off", "--reorder-wait", "0.1",
            "--snapshot-interval", "off", "--status-interval", "0.3", log="fusion",
        )  # fmt: skip
        names = [service_alive_key("recorder"), service_alive_key("fusion")]
        assert wait_for_tokens(s, names, 30.0) == []
        assert start_skyfuse(*sensor, log="sensor-1").wait(timeout=120) == 0
        first = last_payload(status, 2.0, Status.from_json_bytes)
        assert start_skyfuse(*sensor, log="sensor-2").wait(timeout=120) == 0  # same file again
        second = last_payload(status, 2.0, Status.from_json_bytes)
        rec.send_signal(signal.SIGTERM)
        assert rec.wait(timeout=30) == 0
        fusion.send_signal(signal.SIGTERM)
        fusion.wait(timeout=30)
    batches = [
        PlotBatch.from_json_bytes(m.data)
        for m in iter_recording(out)
        if m.topic.startswith(keys.PREFIX) and m.topic.endswith("/plots")
    ]  # fmt: skip
    per_radar: dict[str, list[int]] = {}
    for b in batches:
        per_radar.setdefault(b.radar_id, []).append(b.seq)
    assert max(len(v) for v in per_radar.values()) > LEGACY_RECENT  # beyond the old memory
    assert all(len(v) == len(set(v)) for v in per_radar.values())  # each batch once
    summary = json.loads(stats.read_text())
    assert summary["rejected"].get("duplicate batch") == len(batches)  # every repeat refused
    epochs = {b.epoch for b in batches}
    assert len(epochs) == 1 and 0 not in epochs  # announced: the file's fingerprint
    # the fusion service applied the file once: the second run added no batch, each of
    # its batches refused as a duplicate
    assert first.counters["batches_in"] == second.counters["batches_in"] > LEGACY_RECENT
    assert second.rejected.get("duplicate batch") == first.counters["batches_in"]
    print(json.dumps({"batches": len(batches), "refused_by_recorder": len(batches),
                      "refused_by_fusion": second.rejected.get("duplicate batch")}))  # fmt: skip


class _B:
    """The identity fields of a PlotBatch."""

    def __init__(self, radar_id, epoch, seq) -> None:
        self.radar_id, self.epoch, self.seq = radar_id, epoch, seq
        self.time_end, self.scan = 1000 * seq, seq // 8


@st.composite
def _streams(draw):
    """Batches of 2 radars × 3 epochs, numbers increasing with reordering < 50, and
    repeats of any batch sent earlier."""
    out = []
    for radar in ("A", "B"):
        for epoch in (7, 8, 9):
            n = draw(st.integers(1, 300))
            keys_ = [i + draw(st.integers(0, 49)) for i in range(n)]
            out += [(radar, epoch, s) for _, s in sorted(zip(keys_, range(n)))]
    repeats = draw(st.lists(st.integers(0, len(out) - 1), max_size=200))
    for r in repeats:  # insert a copy of out[r] somewhere after it
        at = draw(st.integers(r + 1, len(out)))
        out.insert(at, out[r])
    return out


@settings(max_examples=200, deadline=None)
@given(stream=_streams())
def test_seen_batches_agrees_with_the_set_of_all_identities(stream):
    seen, ref = SeenBatches(window=64), set()
    for ident in stream:
        b = _B(*ident)
        assert seen.duplicate(b) == (ident in ref), ident
        if ident not in ref:
            seen.add(b)
            ref.add(ident)


def test_epoch_0_keeps_the_old_rule_and_memory_is_bounded():
    seen = SeenBatches(max_radars=3, window=16, epochs=2)
    for s in range(1000):  # no epoch: an exact repeat among the last 256 is a duplicate
        seen.add(_B("A", 0, s))
    assert seen.duplicate(_B("A", 0, 999)) and not seen.duplicate(_B("A", 0, 1000 - 257))
    b = _B("A", 0, 5)
    b.time_end += 1  # a sensor of an earlier version restarted at 0: new data, not refused
    assert not seen.duplicate(b)
    for e in (1, 2, 3):
        for s in range(100):
            seen.add(_B("A", e, s))
    assert set(seen.radars["A"]) == {2, 3}  # at most `epochs` per radar
    assert all(len(v["recent"]) <= 2 * 16 + 1 for v in seen.radars["A"].values())
    for r in "BCDE":
        seen.add(_B(r, 1, 0))
    assert list(seen.radars) == ["C", "D", "E"]  # at most `max_radars`
