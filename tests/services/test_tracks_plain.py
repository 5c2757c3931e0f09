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


def _picture(*tracks) -> TrackBatch:
    return TrackBatch(
        fusion_id="main", kind="full", cycle=3, time=10**18,
        frame={"kind": "stereographic", "lat0": 41.3, "lon0": 2.1},
        state_labels=["x", "vx", "y", "vy"], tracks=list(tracks),
    )  # fmt: skip


def _track(i, status="confirmed", **identity):
    return {
        "track_id": i, "time": 10**18, "status": status, "existence": 0.9,
        "state": [0.0] * 4, "covariance": [[float(r == c) for c in range(4)] for r in range(4)],
        "lat": 41.3, "lon": 2.1, "vel_east": 0.0, "vel_north": 100.0, "speed": 100.0,
        "heading": 0.0, "radars": ["20-129"], **identity,
    }  # fmt: skip


def test_identity_columns_callsign_squawk_and_flight_level():
    b = _picture(
        _track(1, callsign="ROT415", mode_3a=0o4004, flight_level=370.0),
        _track(2, mode_3a=0o7700, emergency="general"),
        _track(3),
    )
    lines = [line.split("\t") for line in plain_table(b, all_tracks=False).splitlines()]
    assert lines[0][:6] == ["id", "status", "callsign", "squawk", "FL", "lat °"]
    assert lines[1][:5] == ["1", "confirmed", "ROT415", "4004", "370"]
    assert lines[2][:5] == ["2", "confirmed", "-", "7700!", "-"]
    assert lines[3][:5] == ["3", "confirmed", "-", "-", "-"]
    assert all(len(row) == len(lines[0]) for row in lines[1:4])

    from io import StringIO

    from rich.console import Console
    from skyfuse.services.cli.cmd_tracks import render_table

    out = StringIO()
    Console(file=out, width=200).print(render_table(b, [], all_tracks=False))
    text = out.getvalue()
    assert "callsign" in text and "ROT415" in text and "7700!" in text


def test_without_identity_the_columns_are_the_ones_they_always_were():
    # a hidden tentative track with a callsign does not add the columns either
    b = _picture(_track(1), _track(2, status="tentative", callsign="DLH65A"))
    header = plain_table(b, all_tracks=False).splitlines()[0].split("\t")
    assert header == ["id", "status", "lat °", "lon °", "alt m", "speed m/s", "hdg °",
                      "P(exist)", "upd", "radars"]  # fmt: skip
    assert "callsign" in plain_table(b, all_tracks=True).splitlines()[0]
