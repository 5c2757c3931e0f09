"""A simulated ``skyfuse sensor`` killed with SIGKILL and restarted continues its
sequence (``services.sensors.continuation``), and the ``skyfuse record`` process next to
it stores every batch once: the recording holds each ``(seq, time_end)`` of the radar at
most once, in increasing order, the restarted sensor's first batch continues after the
first run's last (no restart at seq 0), and the repeats of the last second before the
kill are counted as ``duplicate batch``. Before this guard the recorder stored 500
duplicates of a restarted sensor."""

from __future__ import annotations

import json
import signal
import time

import pytest
from skyfuse.schemas import keys
from skyfuse.services.recording.mcap_io import iter_recording
from skyfuse.services.runtime.transport import (
    TransportConfig,
    free_port,
    open_session,
    service_alive_key,
    wait_for_tokens,
)
from skyfuse.services.sensors.config import SensorServiceConfig
from skyfuse.services.sensors.continuation import (
    SEQ_RESERVE,
    SensorProgress,
    SequenceCeiling,
    selection_fingerprint,
)

pytestmark = pytest.mark.service


def test_restarted_sensor_continues_and_recorder_stores_no_duplicate(
    start_skyfuse, tmp_path, until
):
    ep = f"tcp/127.0.0.1:{free_port()}"
    out, stats = tmp_path / "r.mcap", tmp_path / "stats.json"
    sensor_args = (
        "sensor", "--radar", "LYBE", "--scenario", "regional", "--param", "radars=3",
        "--duration", "120", "--speed", "10", "--connect", ep, "--state-dir", str(tmp_path / "s"),
    )  # fmt: skip
    with open_session(TransportConfig(listen=[ep])) as s:
        rec = start_skyfuse("record", "--out", str(out), "--connect", ep, "--stats", str(stats),
                            "--flush-interval", "0.2", log="recorder")  # fmt: skip
        assert wait_for_tokens(s, [service_alive_key("recorder")], 20.0) == []
        first = start_skyfuse(*sensor_args, log="sensor-1")
        progress = tmp_path / "s" / "progress.json"
        seq = lambda: json.loads(progress.read_text())["seq"] if progress.exists() else -1  # noqa: E731
        assert until(lambda: seq() > 150, 40)
        time.sleep(0.7)  # published after the last progress write: repeated after the restart
        first.send_signal(signal.SIGKILL)
        first.wait()
        saved = seq()
        second = start_skyfuse(*sensor_args, log="sensor-2")
        assert second.wait(timeout=60) == 0
        time.sleep(1.0)
        rec.send_signal(signal.SIGTERM)
        assert rec.wait(timeout=10) == 0
    batches = [
        m.message for m in iter_recording(out, [keys.radar_plots("LYBE")]) if m.message is not None
    ]
    idents = [(b.seq, b.time_end) for b in batches]
    assert len(idents) == len(set(idents))  # no batch stored twice
    seqs = [b.seq for b in batches]
    assert seqs == sorted(seqs) and seqs[0] == 0
    # continuous: at most the batches in flight at the kill are missing
    assert seqs[-1] - seqs[0] + 1 - len(seqs) <= 8
    summary = json.loads(stats.read_text())
    # only what was published after the last progress write is sent again (a sensor
    # restarting from the beginning would repeat all of seq 0..saved)
    assert 1 <= summary["rejected"].get("duplicate batch", 0) < saved


def test_progress_is_resumed_only_for_the_same_selection(tmp_path):
    cfg = SensorServiceConfig(radar="LYBE", scenario="regional", state_dir=tmp_path)
    p = SensorProgress.from_config(cfg)
    assert p.resume_after() is None
    p.published(7, 123)
    p.write()
    assert SensorProgress.from_config(cfg).resume_after() == 123
    other = cfg.model_copy(update={"seed": cfg.seed + 1})
    assert selection_fingerprint(other) != selection_fingerprint(cfg)
    assert SensorProgress.from_config(other).resume_after() is None
    paced = cfg.model_copy(update={"align": 10.0})  # pacing options do not matter
    assert SensorProgress.from_config(paced).resume_after() == 123
    old = cfg.model_copy(update={"resume_max_age": 0.0})
    assert SensorProgress.from_config(old).resume_after() is None


def test_live_sequence_numbers_never_go_back_across_restarts(tmp_path):
    run1 = SequenceCeiling(tmp_path)
    first = [run1.number("R1", k) for k in range(1500)] + [run1.number("R2", 0)]
    assert first[:1500] == list(range(1500)) and first[-1] == 0
    # killed without any clean write: the next run continues above everything published
    run2 = SequenceCeiling(tmp_path)
    second = [run2.number("R1", k) for k in range(10)]
    assert second == sorted(second) and min(second) > max(first[:1500])
    assert min(second) - max(first[:1500]) <= SEQ_RESERVE
    assert run2.number("R2", 0) > 0 and run2.number("R3", 0) == 0
