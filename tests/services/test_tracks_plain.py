"""``skyfuse tracks`` plain output (not a terminal): full precision, one line per track."""

from __future__ import annotations

import math

from skyfuse.schemas import TrackBatch
from skyfuse.services.cli.cmd_tracks import plain_table


def test_plain_table_keeps_every_digit_and_filters_tentative():
    def track(i, status, lat, lon):
        return {
            "track_id": i, "time": 10**18, "status": status, "existence": 0.97,
            "state": [0.0] * 4, "covariance": [[1.0 if r == c else 0.0 for c in range(4)]
                                               for r in range(4)],
            "lat": lat, "lon": lon, "alt": 10_500.0, "vel_east": 200.0, "vel_north": 0.0,
            "speed": 200.0, "heading": math.pi / 2, "radars": ["LYBE", "LYVR"], "updates": 7,
        }  # fmt: skip

    b = TrackBatch(
        fusion_id="main", kind="full", cycle=12, time=10**18,
        frame={"kind": "stereographic", "lat0": 44.8, "lon0": 20.4},
        state_labels=["x", "vx", "y", "vy"],
        tracks=[track(7, "confirmed", 44.8123456, 20.4567891), track(3, "tentative", 45.0, 21.0)],
    )  # fmt: skip
    lines = plain_table(b, all_tracks=False).splitlines()
    assert lines[0].split("\t")[:4] == ["id", "status", "lat °", "lon °"]
    assert lines[1].split("\t") == [
        "7", "confirmed", "44.81235", "20.45679", "10500", "200", "90", "0.970", "7", "LYBE,LYVR"
    ]  # fmt: skip
    assert lines[2] == "# fusion main cycle 12: 1 tracks"
    assert len(plain_table(b, all_tracks=True).splitlines()) == 4
