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


def test_chunk_indexes_are_kept_on_disk_and_the_file_is_unchanged(tmp_path, monkeypatch):
    """The writer holds no ChunkIndex object while it writes (they go to a temporary file
    until the summary), and the file is byte for byte what mcap's own Writer makes keeping
    them in its list; the summary's chunk indexes serve a time-range read."""
    import gc

    from mcap.records import ChunkIndex
    from skyfuse.services.recording import mcap_io

    def alive() -> int:
        return sum(isinstance(o, ChunkIndex) for o in gc.get_objects())

    spilled = tmp_path / "spilled.mcap"
    before = alive()
    w = RecordingWriter(spilled, metadata={"scenario": "unit"}, chunk_size=2_000)
    for i in range(400):
        w.write(keys.radar_plots("r1"), _batch(i), i * 10 + 9)
    assert w.chunk_indexes is not None and w.chunk_indexes.count > 20
    assert alive() == before
    assert list(tmp_path.iterdir()) == [spilled]  # the temporary file has no name
    chunks = w.chunk_indexes.count
    w.close()

    monkeypatch.setattr(mcap_io, "spill_chunk_indexes", lambda writer, directory=None: None)
    kept = tmp_path / "kept.mcap"
    w = RecordingWriter(kept, metadata={"scenario": "unit"}, chunk_size=2_000)
    for i in range(400):
        w.write(keys.radar_plots("r1"), _batch(i), i * 10 + 9)
    assert w.chunk_indexes is None and alive() - before >= chunks  # mcap's own list
    w.close()
    assert spilled.read_bytes() == kept.read_bytes()

    with open(spilled, "rb") as f:
        reader = make_reader(f)
        assert len(reader.get_summary().chunk_indexes) >= chunks
        got = [json.loads(m.data)["seq"] for _, _, m in reader.iter_messages(
            starting_at=1000, ending_before=2000)]  # fmt: skip
    assert got == list(range(100, 200))  # log times 1009 … 1999
