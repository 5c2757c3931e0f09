"""Restart basics of ``skyfuse record`` (docs/reliability.md §3), as real processes on loopback:
a recorder killed with SIGKILL leaves a readable MCAP holding every message received
before its last flush, and a recorder restarted with the same ``--out`` never overwrites
the existing file (it records to ``NAME-1.mcap``)."""

from __future__ import annotations

import hashlib
import signal
import time

import pytest
from skyfuse.schemas import PlotBatch, Status, keys
from skyfuse.services.recording.mcap_io import ReadStats, iter_recording
from skyfuse.services.recording.recorder import Recorder, RecorderConfig
from skyfuse.services.runtime.transport import (
    Inbox,
    TransportConfig,
    declare_publisher,
    free_port,
    open_session,
    service_alive_key,
    wait_for_tokens,
)

pytestmark = pytest.mark.service
T0 = 1_780_000_000_000_000_000


def batch(seq: int) -> bytes:
    t = T0 + seq * 250_000_000
    return PlotBatch(
        radar_id="R1", scan=seq // 16, seq=seq, time_start=t - 1000, time_end=t,
        time=[t - 10, t], range=[1e4, 2e4], azimuth=[0.1, 0.2],
    ).to_json_bytes()  # fmt: skip


def recorded_plots(path) -> tuple[list[int], ReadStats]:
    stats = ReadStats()
    seqs = [
        m.message.seq for m in iter_recording(path, stats=stats) if m.topic.endswith("R1/plots")
    ]
    return seqs, stats


def wait_messages(inbox: Inbox, n: int, timeout: float = 10.0) -> int:
    deadline = time.monotonic() + timeout
    got = 0
    while time.monotonic() < deadline and got < n:
        item = inbox.get(0.1)
        if item is not None:
            got = Status.from_json_bytes(item.payload).counters.get("messages", 0)
    return got


def test_kill_9_leaves_a_readable_file_and_a_restart_does_not_overwrite(tmp_path, start_skyfuse):
    ep = f"tcp/127.0.0.1:{free_port()}"
    out = tmp_path / "rec.mcap"
    args = ("record", "--out", str(out), "--connect", ep, "--flush-interval", "0.2",
            "--status-interval", "0.2", "--key-expr", "skyfuse/@v1/radar/**")  # fmt: skip
    with open_session(TransportConfig(listen=[ep])) as s:
        status = Inbox()
        status.subscribe(s, keys.service_status("recorder"), "status")
        rec = start_skyfuse(*args, log="rec1")
        assert wait_for_tokens(s, [service_alive_key("recorder")], 20.0) == []
        pub = declare_publisher(s, keys.radar_plots("R1"))
        for k in range(200):
            pub.put(batch(k))
        assert wait_messages(status, 200) >= 200
        time.sleep(0.5)  # > flush interval: everything received is in complete chunks
        rec.send_signal(signal.SIGKILL)
        assert rec.wait(5) == -signal.SIGKILL
        seqs, stats = recorded_plots(out)
        assert stats.truncated  # no summary: the writer never finished
        assert seqs == list(range(200))  # nothing lost before the last flush
        digest = hashlib.sha256(out.read_bytes()).hexdigest()

        time.sleep(0.3)
        status.drain()  # the killed recorder's last Status must not count for the new one
        rec2 = start_skyfuse(*args, log="rec2")
        assert wait_for_tokens(s, [service_alive_key("recorder")], 20.0) == []
        for k in range(200, 250):
            pub.put(batch(k))
        assert wait_messages(status, 50) >= 50
        rec2.send_signal(signal.SIGTERM)
        assert rec2.wait(10) == 0
        status.close()
    assert hashlib.sha256(out.read_bytes()).hexdigest() == digest  # untouched
    seqs2, stats2 = recorded_plots(tmp_path / "rec-1.mcap")
    assert seqs2 == list(range(200, 250)) and not stats2.truncated


def test_no_overwrite_names_with_and_without_rotation(tmp_path):
    out = tmp_path / "a.mcap"
    out.write_bytes(b"precious")
    (tmp_path / "a-1.mcap").write_bytes(b"also precious")
    rec = Recorder(RecorderConfig(out=out))
    assert rec.close() == [tmp_path / "a-2.mcap"]
    assert out.read_bytes() == b"precious"
    # rotation: a restart continues after the indices on disk
    rot = tmp_path / "r.mcap"
    for k in (0, 1):
        (tmp_path / f"r-{k:04d}.mcap").write_bytes(b"old")
    rec = Recorder(RecorderConfig(out=rot, rotate_s=1000))
    rec._close_writer()
    rec._open()
    rec.close()
    assert rec.files == [tmp_path / "r-0002.mcap", tmp_path / "r-0003.mcap"]
    assert (tmp_path / "r-0000.mcap").read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["a.mcap", "a-1.mcap", "a-2.mcap", "r-0000.mcap", "r-0001.mcap", "r-0002.mcap",
         "r-0003.mcap"]
    )  # fmt: skip
