"""CAT062 of the fused tracks carries the identity the feed published: the first three
minutes of the Barcelona recording (real CAT048 with Mode-S, callsigns, flight levels)
through the offline runner, every published full picture written as CAT062 and read by
the independent decoder (asterix-decoder): I060 (Mode-3/A, CH), I245 (callsign, STI =
0: downlinked), I380 ADR (Mode-S address) and I136 (measured flight level) equal the
TrackBatch's values, track by track. CH, which no aircraft of that stretch needs, on a
hand-made squawk change."""

from __future__ import annotations

import math

import numpy as np
import pytest
from skyfuse.schemas import PlotBatch, Track, TrackBatch
from skyfuse.services.asterix.cat062_writer import Cat062Writer

BCN_SITES = """[[radar]]
sac = 20
sic = 129
lat = 41.300702
lon = 2.102058
alt = 27.26
"""
MINUTES = 3


@pytest.fixture(scope="module")
def pictures(tmp_path_factory):
    """Full pictures (TrackBatch) every 30 s of the first minutes of the recording."""
    from pathlib import Path

    from service_support import SHARED_DATA
    from skyfuse.fusion.tracker import TrackerConfig
    from skyfuse.services.evaluation.inputs import open_input
    from skyfuse.services.evaluation.offline import Observer, OfflineConfig, run_offline

    path = SHARED_DATA / "bcn_20230502_0800_0815_cat048.ast"
    if not path.exists():
        pytest.skip(f"{path} is absent")
    sites = tmp_path_factory.mktemp("bcn") / "sites.toml"
    sites.write_text(BCN_SITES)
    src = open_input(Path(path), sites_file=sites, date="2023-05-02")
    out: list[TrackBatch] = []

    class Fulls(Observer):
        next_ns = 0

        def on_step(self, step) -> None:
            step.wire()  # the delta of this step (the feed's picture follows it)
            if step.batch.time_end >= self.next_ns:
                self.next_ns = step.batch.time_end + 30 * 10**9
                out.append(step.pipeline.full().model())

    first: list[int] = []

    def stretch():
        for m in src.messages():
            if isinstance(m, PlotBatch):
                first.append(first[0] if first else m.time_end)
                if m.time_end > first[0] + MINUTES * 60 * 10**9:
                    return
            yield m

    run_offline(stretch(), src.sites, OfflineConfig(tracker=TrackerConfig()), [Fulls()])
    return out


def _val(item: dict, *path: str):
    for key in path:
        item = item[key]
    return item["val"]


def test_cat062_shows_what_the_feed_published(pictures, independent_decoder):
    tracks = [t for tb in pictures for t in tb.tracks]
    assert len(tracks) >= 100
    assert sum(t.callsign is not None for t in tracks) >= 0.9 * len(tracks)
    writer = Cat062Writer(sac=20, sic=200)
    data = b"".join(b for tb in pictures for b in writer.encode_batch(tb))
    records = independent_decoder(data)
    assert len(records) == len(tracks)
    for t, r in zip(tracks, records):
        assert _val(r["I040"], "TrkN") == t.track_id % 65536
        if t.mode_3a is None:
            assert "I060" not in r
        else:
            assert _val(r["I060"], "Mode3A") == f"{t.mode_3a:04o}"
            assert _val(r["I060"], "CH") == int(bool(t.mode_3a_changed))
        if t.callsign is None:
            assert "I245" not in r
        else:
            assert _val(r["I245"], "TId").rstrip() == t.callsign
            assert _val(r["I245"], "STI") == 0
        if t.mode_s is None:
            assert "ADR" not in r.get("I380", {})
        else:
            assert _val(r["I380"], "ADR", "ADR") == f"{t.mode_s:06X}"
        fl = t.flight_level
        if fl is None:  # the flight level from the height, as before identity
            fl = t.alt / 0.3048 / 100 if t.alt is not None else None
        if fl is not None:
            assert _val(r["I136"], "MFL") == pytest.approx(fl * 100, abs=12.5)  # ft here


def test_a_changed_code_sets_ch(independent_decoder):
    t = Track(track_id=7, time=1_700_000_000 * 10**9, status="confirmed", existence=0.99,
              state=[0.0, 100.0, 0.0, 0.0], covariance=np.eye(4).tolist(), lat=41.0, lon=2.0,
              vel_east=100.0, vel_north=0.0, speed=100.0, heading=math.pi / 2,
              mode_3a=0o7700, mode_3a_changed=True, emergency="general")  # fmt: skip
    same = t.model_copy(update={"mode_3a_changed": None, "track_id": 8})
    tb = TrackBatch(fusion_id="f", cycle=1, time=t.time, frame={"kind": "stereographic",
                    "lat0": 41.0, "lon0": 2.0}, state_labels=["x", "vx", "y", "vy"],
                    tracks=[t, same])  # fmt: skip
    records = independent_decoder(b"".join(Cat062Writer(sac=1, sic=2).encode_batch(tb)))
    got = [(_val(r["I060"], "Mode3A"), _val(r["I060"], "CH")) for r in records]
    assert got == [("7700", 1), ("7700", 0)]
    assert [_val(r["I080"], "EMS") for r in records] == [1, 1]
