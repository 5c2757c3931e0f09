"""The secondary-surveillance plot columns and track fields (schemas.identity): round
trips, NumPy views, and rejections that name the field, the index and the value."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError
from skyfuse.schemas import Emergency, MeasuredPlot, PlotBatch, Track, TrackBatch
from skyfuse.schemas.identity import (
    DOWNLINKED,
    FT_PER_MIN,
    KT,
    emergency_of_code,
    mode_3a_text,
)
from skyfuse.schemas.plots import IDENTITY_COLUMNS, OPTIONAL_PLOT_COLUMNS
from skyfuse.schemas.rejection import decode, rejection_reason


def batch(n: int = 4, **cols) -> dict:
    return {
        "radar_id": "20-129",
        "scan": 1,
        "seq": 2,
        "time_start": 1_000,
        "time_end": 2_000,
        "time": list(range(1_100, 1_100 + n)),
        "range": [1e4] * n,
        "azimuth": [0.5] * n,
        **cols,
    }


FULL = {
    "mode_3a": [0o7700, None, 0o1234, 4095],
    "mode_3a_not_validated": [False, None, True, False],
    "mode_3a_garbled": [False, None, False, True],
    "mode_3a_smoothed": [True, None, False, False],
    "mode_s": [0x4CA73D, None, 1, 0xFFFFFF],
    "callsign": ["DLH65A", None, "N501MG", "AB 12"],
    "flight_level": [330.0, None, -12.0, 2047.75],
    "flight_level_not_validated": [False, None, True, False],
    "flight_level_garbled": [False, None, False, True],
    "spi": [True, None, False, False],
    "flight_status": [0, None, 5, 7],
    **{q.name: [q.lo, None, 0.5 * (q.lo + q.hi), q.hi * (0.999 if q.hi_open else 1.0)]
       for q in DOWNLINKED},
}  # fmt: skip


def test_every_identity_column_is_an_optional_plot_column_with_a_description():
    assert set(FULL) == set(IDENTITY_COLUMNS) <= set(OPTIONAL_PLOT_COLUMNS)
    for name in IDENTITY_COLUMNS:
        text = PlotBatch.model_fields[name].description
        assert text and "null" in text, name
    for q in DOWNLINKED:  # the unit is in every description (SI, FL for altitudes)
        assert (q.unit or "Mach") in PlotBatch.model_fields[q.name].description


def test_round_trip_and_numpy_views():
    b = PlotBatch(**batch(**FULL))
    b2 = PlotBatch.from_json_bytes(b.to_json_bytes())
    assert b2 == b
    assert b2.column("mode_3a").tolist() == [0o7700, -1, 0o1234, 4095]
    assert b2.column("flight_status").dtype == np.int64
    assert b2.column("spi").tolist() == [True, False, False, False]
    assert b2.column("callsign").tolist() == ["DLH65A", "", "N501MG", "AB 12"]
    fl = b2.column("flight_level")
    assert np.isnan(fl[1]) and fl[0] == 330.0
    # validated values: not-validated or garbled replies removed
    assert b2.validated_column("mode_3a").tolist() == [0o7700, -1, -1, -1]
    vfl = b2.validated_column("flight_level")
    assert vfl[0] == 330.0 and np.isnan(vfl[1:]).all()
    assert b2.column("mode_3a").tolist() == [0o7700, -1, 0o1234, 4095]  # untouched


def test_absent_columns_cost_nothing_and_flags_default_to_false():
    b = PlotBatch(**batch(mode_3a=[1, 2, 3, 4]))
    assert b.to_json_bytes().count(b"null") == 0
    assert b.mode_3a_garbled is None and b.column("spi") is None
    assert b.validated_column("mode_3a").tolist() == [1, 2, 3, 4]


@pytest.mark.parametrize(
    ("column", "values", "message"),
    [
        ("callsign", ["DLH65A", "dlh65a", None, None], "callsign[1] = 'dlh65a': must be 1-8"),
        ("callsign", [None, None, "ABCDEFGHI", None], "callsign[2] = 'ABCDEFGHI'"),
        ("callsign", [" AB", None, None, None], "callsign[0] = ' AB'"),
        ("callsign", ["AB ", None, None, None], "callsign[0] = 'AB '"),
        ("flight_level", [1.0, 2049.0, None, None], "flight_level[1] = 2049.0: must be <= 2048"),
        ("mach", [None, None, None, 4.2], "mach[3] = 4.2: must be <= 4.1"),
        ("true_track", [2 * math.pi, None, None, None], "true_track[0] = 6.28"),
        ("ground_speed", [-1.0, None, None, None], "ground_speed[0] = -1.0: must be >= 0.0 m/s"),
        ("flight_status", [0, 8, None, None], "flight_status[1] = 8: must be in 0..7"),
        ("mode_3a", [0o10000, None, None, None], "mode_3a[0] = 4096: must be in 0..4095"),
        ("roll_angle", [None, math.inf, None, None], "roll_angle.1\n  Input should be a finite"),
    ],
)  # fmt: skip
def test_rejections_name_field_index_and_value(column, values, message):
    with pytest.raises(ValidationError) as e:
        PlotBatch(**batch(**{column: values}))
    assert message in str(e.value)
    if column == "roll_angle":
        return  # JSON has no inf: on the wire this is a type error (null) or not JSON
    raw = PlotBatch.model_construct(**batch(**{column: values})).model_dump_json()
    msg, exc = decode(PlotBatch, raw)
    assert msg is None and rejection_reason(PlotBatch, exc) == f"invalid PlotBatch: {column}"


def test_columns_of_unequal_length_are_rejected():
    with pytest.raises(ValidationError, match="column 'callsign' has 3 values"):
        PlotBatch(**batch(callsign=["A", "B", "C"]))


def test_register_extremes_are_within_the_bounds():
    """The largest values the registers can carry (ICAO Doc 9871: 1023 × 2 kt, 1023 kt,
    ±511 × 32 ft/min, ±511 × 8/256 °/s, ±511 × 45/256 °, 4095 × 16 ft) are valid."""
    extremes = {
        "ground_speed": 2046 * KT, "true_airspeed": 2046 * KT, "indicated_airspeed": 1023 * KT,
        "mach": 1023 * 2.048 / 512, "baro_vertical_rate": -512 * 32 * FT_PER_MIN,
        "inertial_vertical_rate": 511 * 32 * FT_PER_MIN,
        "track_angle_rate": math.radians(-512 * 8 / 256), "roll_angle": math.radians(-90.0),
        "selected_altitude_mcp": 4095 * 16 / 100, "selected_altitude_fms": 4095 * 16 / 100,
    }  # fmt: skip
    PlotBatch(**batch(**{k: [v] * 4 for k, v in extremes.items()}))


def _track(**kw) -> dict:
    return {
        "track_id": 7,
        "time": 5_000,
        "status": "confirmed",
        "existence": 0.99,
        "state": [0.0, 1.0, 0.0, 1.0],
        "covariance": np.eye(4).tolist(),
        "lat": 41.3,
        "lon": 2.1,
        "vel_east": 1.0,
        "vel_north": 1.0,
        "speed": 1.4,
        "heading": 0.78,
        **kw,
    }


def test_track_identity_round_trip():
    last = MeasuredPlot(radar_id="20-129", time=4_900, range=5e4, azimuth=1.0, plot_type=5,
                        flight_level=330.0, mode_3a=0o4004, mode_3a_smoothed=True)  # fmt: skip
    t = Track(**_track(mode_3a=0o7700, mode_3a_time=4_900, mode_s=0x4CA73D, mode_s_time=4_900,
                       callsign="ROT415", callsign_time=4_000, flight_level=370.0,
                       flight_level_time=4_900, spi=False, emergency="general",
                       selected_altitude_mcp=370.08, intention_time=3_000, ground_speed=210.0,
                       true_track=4.55, track_turn_time=4_900, mach=0.752,
                       heading_speed_time=4_100, psr_time=4_900, mode_s_update_time=4_900,
                       last_plot=last))  # fmt: skip
    tb = TrackBatch(fusion_id="main", cycle=1, time=5_000, frame={"kind": "stereographic"},
                    state_labels=["x", "vx", "y", "vy"], tracks=[t])  # fmt: skip
    back = TrackBatch.from_json_bytes(tb.to_json_bytes())
    assert back == tb and back.tracks[0].emergency is Emergency.GENERAL
    assert back.tracks[0].last_plot.mode_3a_smoothed
    plain = Track(**_track())  # no identity: the same JSON as before the fields existed
    assert b"mode_3a" not in plain.to_json_bytes() and b"last_plot" not in plain.to_json_bytes()


@pytest.mark.parametrize(
    ("field", "value", "fragment"),
    [
        ("callsign", "rot415", "String should match pattern"),
        ("mode_3a", 4096, "less than or equal to 4095"),
        ("mode_s", 2**24, "less than or equal to 16777215"),
        ("flight_level", 3000.0, "less than or equal to 2048"),
        ("emergency", "panic", "Input should be"),
        ("true_track", 2 * math.pi, "less than 6.28"),
        ("mode_3a_time", -1, "greater than or equal to 0"),
    ],
)
def test_track_identity_rejections(field, value, fragment):
    with pytest.raises(ValidationError) as e:
        Track(**_track(**{field: value}))
    assert fragment in str(e.value) and field in str(e.value)


def test_emergency_codes_and_octal_text():
    assert emergency_of_code(0o7700) is Emergency.GENERAL
    assert emergency_of_code(0o7600) is Emergency.NO_COMMUNICATIONS
    assert emergency_of_code(0o7500) is Emergency.UNLAWFUL_INTERFERENCE
    assert emergency_of_code(0o7777) is None and emergency_of_code(None) is None
    assert mode_3a_text(0o1000) == "1000" and mode_3a_text(7) == "0007"
    assert mode_3a_text(None) == "" and mode_3a_text(-1) == ""


def test_identity_events_status_and_change_flag_round_trip():
    from skyfuse.schemas import Status
    from skyfuse.schemas.status import IdentityStatus
    from skyfuse.schemas.tracks import TrackEvent, TrackEventKind

    for kind, attribute, value, previous in [
        ("identity_changed", "mode_3a", "7700", "4004"),
        ("identity_conflict", "mode_s", "4CA73D", "3C6586"),
        ("identity_conflict", "callsign", "ROT415", "DLH65A"),
        ("emergency", "mode_3a", "7500", None),
        ("spi", "spi", None, None),
    ]:
        ev = TrackEvent(fusion_id="m", time=5, kind=kind, track_id=7, existence=0.9,
                        attribute=attribute, value=value, previous=previous)  # fmt: skip
        back = TrackEvent.from_json_bytes(ev.to_json_bytes())
        assert back == ev and back.kind is TrackEventKind(kind)
    with pytest.raises(ValidationError, match="attribute"):
        TrackEvent(fusion_id="m", time=5, kind="spi", track_id=7, existence=0.9,
                   attribute="squawk")  # fmt: skip
    with pytest.raises(ValidationError, match="value"):
        TrackEvent(fusion_id="m", time=5, kind="identity_changed", track_id=7, existence=0.9,
                   attribute="callsign", value="A" * 9)  # fmt: skip
    st = Status(service="fusion", service_id="main", time=1, uptime_s=2.0,
                identity=IdentityStatus(conflicts=3, changes=2, emergencies=1, spi=4,
                                        tracks_in_emergency=1))  # fmt: skip
    assert Status.from_json_bytes(st.to_json_bytes()) == st
    with pytest.raises(ValidationError, match="conflicts"):
        IdentityStatus(conflicts=-1)
    t = Track(**_track(mode_3a=0o7700, mode_3a_time=4_900, mode_3a_changed=True))
    assert Track.from_json_bytes(t.to_json_bytes()).mode_3a_changed is True
    assert b"mode_3a_changed" not in Track(**_track()).to_json_bytes()
