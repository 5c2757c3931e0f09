"""MCAP recordings: readable by the plain mcap reader, pass `pymcap-cli doctor`, and a
recording whose writer was killed still yields its complete chunks."""

from __future__ import annotations

import io
import json
import shutil
import subprocess

import pytest
from mcap.reader import make_reader
from skyfuse.schemas import PlotBatch, RadarSite, keys
from skyfuse.services.recording.mcap_io import (
    ReadStats,
    RecordingWriter,
    iter_recording,
    read_metadata,
)


def _batch(i: int) -> PlotBatch:
    return PlotBatch(
        radar_id="r1",
        scan=i // 4,
        seq=i,
        time_start=i * 10,
        time_end=i * 10 + 9,
        time=[i * 10, i * 10 + 5],
        range=[1000.0 + i, 2000.0],
        azimuth=[0.1, 0.2],
    )


def _write(path, n=50, **kw):
    site = RadarSite(radar_id="r1", lat=44.8, lon=20.4, kind="2d")
    with RecordingWriter(path, metadata={"scenario": "unit"}, **kw) as w:
        w.write(keys.radar_site("r1"), site, 0)
        for i in range(n):
            w.write(keys.radar_plots("r1"), _batch(i), i * 10 + 9)
    return site


def test_plain_mcap_reader_reads_json_with_schema(tmp_path):
    path = tmp_path / "a.mcap"
    site = _write(path)
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        topics = {c.topic for c in summary.channels.values()}
        assert topics == {keys.radar_site("r1"), keys.radar_plots("r1")}
        msgs = list(reader.iter_messages())
    assert len(msgs) == 51
    schema, channel, msg = msgs[0]
    assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
    assert json.loads(schema.data)["title"] == "RadarSite"
    assert RadarSite.model_validate(json.loads(msg.data)) == site
    seqs = [json.loads(m.data)["seq"] for _, c, m in msgs if c.topic.endswith("/plots")]
    assert seqs == list(range(50))
    assert read_metadata(path)["skyfuse"] == {"scenario": "unit"}


def test_iter_recording_decodes_and_counts_bad_messages(tmp_path):
    path = tmp_path / "b.mcap"
    with RecordingWriter(path) as w:
        w.write(keys.radar_plots("r1"), _batch(0), 1)
        # a corrupt payload on a plots topic: negative range
        bad = _batch(1).model_dump()
        bad["range"][0] = -5.0
        w.write(keys.radar_plots("r1"), json.dumps(bad).encode(), 2, model=PlotBatch)
        w.write(keys.radar_plots("r1"), b"{not json", 3, model=PlotBatch)
        w.write(keys.radar_plots("r1"), _batch(2), 4)
    stats = ReadStats()
    got = list(iter_recording(path, stats=stats))
    assert [r.message.seq for r in got] == [0, 2]
    assert stats.rejected == {"invalid PlotBatch": 2}
    assert any("range" in e for e in stats.errors)


def test_killed_writer_keeps_complete_chunks(tmp_path):
    buf = io.BytesIO()
    w = RecordingWriter(buf, chunk_size=2_000)
    sizes = []
    for i in range(200):
        w.write(keys.radar_plots("r1"), _batch(i), i)
        sizes.append(len(buf.getvalue()))
    # The process dies here: no finish(), no summary. Only flushed chunks are on disk,
    # and the last chunk written was cut mid-record (the one before the last growth).
    data = buf.getvalue()
    last_chunk_start = max(s for s in sizes if s < len(data))
    path = tmp_path / "killed.mcap"
    path.write_bytes(data[: (last_chunk_start + len(data)) // 2])
    stats = ReadStats()
    got = list(iter_recording(path, stats=stats))
    assert stats.truncated
    assert 150 <= len(got) < 200
    assert [r.message.seq for r in got] == list(range(len(got)))


@pytest.mark.skipif(shutil.which("pymcap-cli") is None, reason="pymcap-cli not installed")
def test_pymcap_doctor_passes(tmp_path):
    path = tmp_path / "d.mcap"
    _write(path, n=20)
    res = subprocess.run(
        ["pymcap-cli", "doctor", str(path)], capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 0, res.stdout + res.stderr
    assert "passed" in res.stdout
