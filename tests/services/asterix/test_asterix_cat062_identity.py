"""CAT062 identity items (I060, I245, I380, I080 SPI/EMS, I136 from the measured flight
level, I290, I295, I340): written from the track fields, read back by libasterix (our
reader) and by an independent decoder (asterix-decoder, in a virtualenv of its own),
and unchanged output for tracks without identity."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest
from skyfuse.schemas import MeasuredPlot, Track, TrackBatch
from skyfuse.schemas.identity import FT_PER_MIN, KT
from skyfuse.services.asterix.cat062 import decode_cat062
from skyfuse.services.asterix.cat062_writer import Cat062Writer, build_record, pack_record

T0 = int(dt.datetime(2026, 3, 1, 12, 0, tzinfo=dt.UTC).timestamp()) * 10**9
S = 1_000_000_000
EMERGENCIES = [None, "general", "medical", "minimum_fuel", "no_communications",
               "unlawful_interference", "downed_aircraft"]  # fmt: skip


def plain_track(i: int, rng) -> Track:
    ve, vn = rng.uniform(-250, 250, 2)
    return Track(
        track_id=i,
        time=T0 + i * 1_000_000,
        status="confirmed",
        existence=0.95,
        state=[float(x) for x in rng.uniform(-2e5, 2e5, 4)],
        covariance=np.diag([100.0**2, 4.0, 120.0**2, 4.0]).tolist(),
        lat=float(rng.uniform(40, 45)),
        lon=float(rng.uniform(0, 5)),
        alt=9000.0,
        vel_east=float(ve),
        vel_north=float(vn),
        speed=float(math.hypot(ve, vn)),
        heading=float(math.atan2(ve, vn) % (2 * math.pi)),
        radars=["20-129"],
    )


def identity_track(i: int, rng) -> Track:
    """A track with every identity field, values anywhere in their items' ranges."""
    t = plain_track(i, rng)
    now = t.time
    ago = lambda s: now - int(s * S)  # noqa: E731
    letters = "ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"
    callsign = "".join(letters[k] for k in rng.integers(0, 36, int(rng.integers(1, 9))))
    last = MeasuredPlot(
        radar_id=("20-129", "LYBE")[i % 2], time=ago(0.1), range=float(rng.uniform(0, 4e5)),
        azimuth=float(rng.uniform(0, 2 * math.pi)), plot_type=int(rng.integers(1, 8)),
        flight_level=float(rng.uniform(-10, 450)), flight_level_garbled=bool(i % 3 == 0),
        mode_3a=int(rng.integers(0, 4096)), mode_3a_smoothed=bool(i % 2),
        mode_3a_not_validated=bool(i % 5 == 0),
    )  # fmt: skip
    fields = {
        "mode_3a": int(rng.integers(0, 4096)), "mode_3a_time": ago(rng.uniform(0, 70)),
        "mode_s": int(rng.integers(0, 2**24)), "mode_s_time": ago(1),
        "callsign": callsign, "callsign_time": ago(3),
        "flight_level": float(rng.uniform(-10, 450)), "flight_level_time": ago(rng.uniform(0, 9)),
        "spi": bool(i % 2), "emergency": EMERGENCIES[i % len(EMERGENCIES)],
        "selected_altitude_mcp": float(rng.uniform(0, 450)),
        "selected_altitude_fms": None if i % 2 else float(rng.uniform(0, 450)),
        "intention_time": ago(rng.uniform(0, 20)),
        "roll_angle": float(rng.uniform(-0.6, 0.6)),
        "true_track": float(rng.uniform(0, 2 * math.pi)),
        "ground_speed": float(rng.uniform(0, 300)),
        "track_angle_rate": float(rng.uniform(-0.05, 0.05)),
        "true_airspeed": float(rng.uniform(0, 300)), "track_turn_time": ago(rng.uniform(0, 20)),
        "magnetic_heading": float(rng.uniform(0, 2 * math.pi)),
        "indicated_airspeed": None if i % 4 == 1 else float(rng.uniform(0, 200)),
        "mach": float(rng.uniform(0.1, 0.9)),
        "baro_vertical_rate": float(rng.uniform(-20, 20)),
        "inertial_vertical_rate": float(rng.uniform(-20, 20)),
        "heading_speed_time": ago(rng.uniform(0, 20)),
        "psr_time": ago(rng.uniform(0, 80)), "ssr_time": ago(rng.uniform(0, 20)),
        "mode_s_update_time": ago(rng.uniform(0, 20)), "last_plot": last,
    }  # fmt: skip
    return t.model_copy(update=fields)


def batch_of(tracks) -> TrackBatch:
    return TrackBatch(fusion_id="f", cycle=1, time=T0, frame={"kind": "stereographic",
                      "lat0": 41.0, "lon0": 2.0}, state_labels=["x", "vx", "y", "vy"],
                      tracks=tracks)  # fmt: skip


def angle_diff(a: float, b: float) -> float:
    return (a - b + math.pi) % (2 * math.pi) - math.pi


def age(t: Track, when: int) -> float:
    return min((t.time - when) / S, 63.75)


@pytest.fixture(scope="module")
def tracks():
    rng = np.random.default_rng(11)
    return [identity_track(i, rng) for i in range(40)]


def test_round_trip_through_our_reader(tracks):
    blocks = Cat062Writer(sac=25, sic=100).encode_batch(batch_of(tracks))
    got = [d for b in blocks for d in decode_cat062(b)]
    assert len(got) == len(tracks)
    for t, d in zip(tracks, got):
        assert (d.mode_3a, d.mode_s, d.callsign) == (t.mode_3a, t.mode_s, t.callsign)
        assert d.flight_level == pytest.approx(t.flight_level, abs=0.125)  # I136: measured
        assert d.spi == t.spi and d.emergency == t.emergency
        dl = d.downlinked
        assert dl["selected_altitude_mcp"] == pytest.approx(t.selected_altitude_mcp, abs=0.125)
        sal = t.selected_altitude_fms if t.selected_altitude_fms is not None else (
            t.selected_altitude_mcp)  # fmt: skip
        assert dl["selected_altitude"] == pytest.approx(sal, abs=0.125)
        assert dl["selected_altitude_source"] == (3 if t.selected_altitude_fms is not None else 2)
        assert abs(angle_diff(dl["magnetic_heading"], t.magnetic_heading)) <= math.radians(0.003)
        assert abs(angle_diff(dl["true_track"], t.true_track)) <= math.radians(0.003)
        assert dl["roll_angle"] == pytest.approx(t.roll_angle, abs=math.radians(0.005))
        assert dl["true_airspeed"] == pytest.approx(t.true_airspeed, abs=0.5 * KT)
        assert dl["ground_speed"] == pytest.approx(t.ground_speed, abs=1852 * 2**-15)
        assert dl["mach"] == pytest.approx(t.mach, abs=0.004)  # MAC, 0.008
        if t.indicated_airspeed is not None:
            assert dl["indicated_airspeed"] == pytest.approx(
                t.indicated_airspeed, abs=1852 * 2**-15
            )
        assert dl["baro_vertical_rate"] == pytest.approx(t.baro_vertical_rate, abs=3.2 * FT_PER_MIN)
        assert dl["inertial_vertical_rate"] == pytest.approx(t.inertial_vertical_rate,
                                                             abs=3.2 * FT_PER_MIN)  # fmt: skip
        assert dl["track_angle_rate"] == pytest.approx(t.track_angle_rate, abs=math.radians(0.125))
        assert dl["turn_indicator"] == (2 if t.track_angle_rate > 0 else 1)
        assert d.ages["PSR"] == pytest.approx(age(t, t.psr_time), abs=0.125)
        assert d.ages["MDS"] == pytest.approx(age(t, t.mode_s_update_time), abs=0.125)
        assert d.data_ages["MFL"] == pytest.approx(age(t, t.flight_level_time), abs=0.125)
        assert d.data_ages["MDA"] == pytest.approx(age(t, t.mode_3a_time), abs=0.125)
        assert d.data_ages["GSP"] == pytest.approx(age(t, t.track_turn_time), abs=0.125)
        assert d.data_ages["MHG"] == pytest.approx(age(t, t.heading_speed_time), abs=0.125)
        assert d.data_ages["SAL"] == pytest.approx(age(t, t.intention_time), abs=0.125)
        lp, p = d.last_plot, t.last_plot
        assert lp.get("radar_id") == ("20-129" if p.radar_id == "20-129" else None)
        assert lp["rho_nm"] == pytest.approx(p.range / 1852, abs=1 / 512)
        assert abs(angle_diff(math.radians(lp["theta_deg"]), p.azimuth)) <= math.pi / 65536
        assert lp["flight_level"] == pytest.approx(p.flight_level, abs=0.125)
        assert lp["flight_level_garbled"] == p.flight_level_garbled
        assert (lp["mode_3a"], lp["mode_3a_smoothed"], lp["mode_3a_not_validated"]) == (
            p.mode_3a, p.mode_3a_smoothed, p.mode_3a_not_validated)  # fmt: skip
        assert lp["plot_type"] == p.plot_type


def test_direct_encoder_matches_libasterix(tracks):
    writer = Cat062Writer(sac=3, sic=4)
    for t in tracks:
        raw = writer.raw_items(t, "stereographic", ["x", "vx", "y", "vy"], first=True, last=False)
        assert pack_record(raw) == build_record(raw).unparse().to_bytes()


def test_tracks_without_identity_give_the_items_they_always_had():
    rng = np.random.default_rng(2)
    t = plain_track(1, rng)
    raw = Cat062Writer(sac=1, sic=2).raw_items(t, "stereographic", ["x", "vx", "y", "vy"],
                                                first=True, last=False)  # fmt: skip
    assert set(raw) == {"010", "015", "070", "105", "100", "185", "040", "080", "136", "500"}
    data = pack_record(raw)
    assert data == build_record(raw).unparse().to_bytes()
    (d,) = decode_cat062(bytes([62]) + (len(data) + 3).to_bytes(2, "big") + data)
    assert d.flight_level == pytest.approx(9000.0 / 30.48, abs=0.125)  # from alt, as before
    assert (d.mode_3a, d.callsign, d.spi, d.emergency, d.downlinked) == (None, None, False,
                                                                          None, {})  # fmt: skip


def test_values_beyond_their_item_are_clipped_and_counted():
    rng = np.random.default_rng(3)
    t = plain_track(1, rng).model_copy(update={"track_angle_rate": 0.29, "psr_time": T0 - 600 * S})
    w = Cat062Writer(sac=1, sic=2)
    (d,) = decode_cat062(w.encode_batch(batch_of([t]))[0])
    assert d.downlinked["track_angle_rate"] == pytest.approx(math.radians(63 * 0.25))
    assert w.stats["identity_value_clipped"] == 1
    assert d.ages["PSR"] == 63.75


def test_an_independent_decoder_reads_what_we_wrote(tracks, independent_decoder):
    data = b"".join(Cat062Writer(sac=25, sic=100).encode_batch(batch_of(tracks)))
    records = independent_decoder(data)
    assert len(records) == len(tracks)
    for t, r in zip(tracks, records):
        v = lambda item, *path, rec=r: _val(rec[item], *path)  # noqa: E731
        assert v("I010", "SAC") == 25 and v("I040", "TrkN") == t.track_id
        assert v("I060", "Mode3A") == f"{t.mode_3a:04o}" and v("I060", "V") == 0
        assert v("I245", "TId").rstrip() == t.callsign and v("I245", "STI") == 0
        assert v("I380", "ADR", "ADR") == f"{t.mode_s:06X}"
        assert v("I380", "ID", "ACID").rstrip() == t.callsign
        assert v("I136", "MFL") == pytest.approx(t.flight_level * 100, abs=12.5)  # ft here
        assert v("I080", "SPI") == int(t.spi)
        assert v("I080", "EMS") if t.emergency else "EMS" not in r["I080"]
        assert v("I380", "FSS", "Alt") == pytest.approx(t.selected_altitude_mcp * 100, abs=12.5)
        mhg = math.radians(v("I380", "MHG", "MAH"))
        assert abs(angle_diff(mhg, t.magnetic_heading)) <= math.radians(0.003)
        assert v("I380", "TAS", "TAS") == pytest.approx(t.true_airspeed / KT, abs=0.5)
        assert v("I380", "BVR", "BVR") == pytest.approx(t.baro_vertical_rate / FT_PER_MIN, abs=3.2)
        assert v("I380", "GVR", "GVR") == pytest.approx(t.inertial_vertical_rate / FT_PER_MIN,
                                                        abs=3.2)  # fmt: skip
        assert v("I380", "RAN", "RAN") == pytest.approx(math.degrees(t.roll_angle), abs=0.005)
        assert v("I380", "TAR", "RoT") == pytest.approx(math.degrees(t.track_angle_rate),
                                                        abs=0.125)  # fmt: skip
        tan = math.radians(v("I380", "TAN", "TAN"))
        assert abs(angle_diff(tan, t.true_track)) <= math.radians(0.003)
        assert v("I380", "GSP", "GS") * 1852 == pytest.approx(t.ground_speed, abs=1852 * 2**-15)
        assert v("I380", "MAC", "MNO") == pytest.approx(t.mach, abs=0.004)
        assert v("I290", "PSR", "PSR") == pytest.approx(age(t, t.psr_time), abs=0.125)
        assert v("I295", "MFL", "MFL") == pytest.approx(age(t, t.flight_level_time), abs=0.125)
        assert v("I295", "GSP", "GSP") == pytest.approx(age(t, t.track_turn_time), abs=0.125)
        p = t.last_plot
        assert v("I340", "POS", "RHO") == pytest.approx(p.range / 1852, abs=1 / 512)
        assert v("I340", "MDC", "ModeC") == pytest.approx(p.flight_level, abs=0.125)
        assert v("I340", "MDA", "Mode3A") == f"{p.mode_3a:04o}"
        assert v("I340", "MDA", "L") == int(p.mode_3a_smoothed)
        assert v("I340", "TYP", "TYP") == p.plot_type
        if p.radar_id == "20-129":
            assert (v("I340", "SID", "SAC"), v("I340", "SID", "SIC")) == (20, 129)


def _val(item: dict, *path: str):
    for key in path:
        item = item[key]
    return item["val"]
