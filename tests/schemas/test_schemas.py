"""Wire-contract tests: round trips, and rejections that name the field and the value."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError
from skyfuse import schemas
from skyfuse.schemas import PlotBatch, RadarSite, Status, Track, TrackBatch, TrackEvent, Truth, keys


def make_batch(n: int = 5, **overrides) -> dict:
    rng = np.random.default_rng(0)
    data = {
        "radar_id": "r1",
        "scan": 3,
        "seq": 17,
        "sector_start": 0.5,
        "sector_width": 2 * math.pi / 16,
        "time_start": 1_000,
        "time_end": 2_000,
        "time": sorted(int(t) for t in rng.integers(1_000, 2_000, n)),
        "range": rng.uniform(1e3, 2e5, n).tolist(),
        "azimuth": rng.uniform(0.5, 0.8, n).tolist(),
        "altitude": [*rng.uniform(0, 1e4, n - 1).tolist(), None] if n else [],
        "mode_s": [0xABCDEF] + [None] * (n - 1) if n else [],
    }
    data.update(overrides)
    return data


def test_plot_batch_round_trip_json_and_numpy():
    b = PlotBatch(**make_batch(6))
    b2 = PlotBatch.from_json_bytes(b.to_json_bytes())
    assert b2 == b
    alt = b2.column("altitude")
    assert np.isnan(alt[-1]) and np.isfinite(alt[:-1]).all()
    assert b2.column("mode_s")[0] == 0xABCDEF and b2.column("mode_s")[1] == -1
    assert b2.column("time").dtype == np.int64


def test_empty_batch_is_valid():
    b = PlotBatch(radar_id="r1", scan=0, seq=0, time_start=0, time_end=0)
    assert len(b) == 0
    assert PlotBatch.from_json_bytes(b.to_json_bytes()) == b


@pytest.mark.parametrize(
    ("overrides", "field", "fragment"),
    [
        ({"range": [1.0, -5.0, 1.0, 1.0, 1.0]}, "range[1]", "-5.0"),
        ({"azimuth": [0.1, 0.1, 7.0, 0.1, 0.1]}, "azimuth[2]", "7.0"),
        ({"azimuth": [0.1, 0.1, 2 * math.pi, 0.1, 0.1]}, "azimuth[2]", "< 6.28"),
        ({"time": [5, 4, 6, 7, 8]}, "time[1]", "earlier"),
        ({"range": [1.0, 2.0]}, "range", "has 2 values"),
        ({"altitude": [1.0, math.inf, 1.0, 1.0, 1.0]}, "altitude", "finite"),
        ({"mode_s": [1 << 25, None, None, None, None]}, "mode_s[0]", "0..16777215"),
        ({"time_end": 10}, "time_end", "earlier than time_start"),
    ],
)
def test_plot_batch_rejections_name_field_and_value(overrides, field, fragment):
    with pytest.raises(ValidationError) as exc:
        PlotBatch(**make_batch(5, **overrides))
    text = str(exc.value)
    assert field in text and fragment in text


def test_nan_in_json_is_rejected_with_field_location():
    raw = json.dumps(make_batch(3)).replace('"range": [', '"range": [NaN, ', 1)
    raw = raw.replace('"time": [', '"time": [1000, ', 1)  # keep lengths equal
    with pytest.raises(ValidationError) as exc:
        PlotBatch.from_json_bytes(raw.encode())
    assert "range" in str(exc.value)


def test_polar_and_cartesian_are_exclusive_and_complete():
    with pytest.raises(ValidationError, match="not both"):
        PlotBatch(**make_batch(2, x=[1.0, 2.0], y=[1.0, 2.0], altitude=None, mode_s=None))
    with pytest.raises(ValidationError, match="'azimuth' is missing"):
        PlotBatch(**make_batch(2, azimuth=None, altitude=None, mode_s=None))
    cart = PlotBatch(
        radar_id="c",
        scan=0,
        seq=0,
        time_start=0,
        time_end=0,
        time=[0, 0],
        x=[1.0, -2.0],
        y=[3.0, 4.0],
    )
    assert cart.is_cartesian


# ---- hypothesis: any corruption of a valid batch is rejected, never accepted silently -------
FLOAT_COLUMNS = ["range", "azimuth"]


@settings(max_examples=150, deadline=None)
@given(
    n=st.integers(1, 40),
    column=st.sampled_from(FLOAT_COLUMNS),
    bad=st.sampled_from([math.nan, math.inf, -math.inf, -1.0, 100.0]),
    data=st.data(),
)
def test_hypothesis_bad_values_rejected(n, column, bad, data):
    base = make_batch(n)
    if column == "range" and bad == 100.0:
        bad = -100.0  # 100 m is a valid range
    i = data.draw(st.integers(0, n - 1))
    base[column] = list(base[column])
    base[column][i] = bad
    with pytest.raises(ValidationError) as exc:
        PlotBatch(**base)
    assert column in str(exc.value)


@settings(max_examples=100, deadline=None)
@given(n=st.integers(2, 40), drop=st.sampled_from(["range", "azimuth", "time", "altitude"]))
def test_hypothesis_unequal_lengths_rejected(n, drop):
    base = make_batch(n)
    base[drop] = list(base[drop])[:-1]
    with pytest.raises(ValidationError, match="values"):
        PlotBatch(**base)


@settings(max_examples=100, deadline=None)
@given(times=st.lists(st.integers(0, 10**12), min_size=2, max_size=30))
def test_hypothesis_time_order(times):
    n = len(times)
    base = make_batch(n, time=times, time_start=0, time_end=10**12)
    if all(a <= b for a, b in itertools.pairwise(times)):
        assert len(PlotBatch(**base)) == n
    else:
        with pytest.raises(ValidationError, match="non-decreasing"):
            PlotBatch(**base)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(0, 30),
    seed=st.integers(0, 2**32 - 1),
)
def test_hypothesis_valid_round_trip(n, seed):
    rng = np.random.default_rng(seed)
    b = PlotBatch(
        radar_id="rr",
        scan=1,
        seq=2,
        time_start=0,
        time_end=10**9,
        time=sorted(rng.integers(0, 10**9, n).tolist()),
        range=rng.uniform(0, 3e5, n).tolist(),
        azimuth=rng.uniform(0, 2 * math.pi, n).clip(0, 2 * math.pi - 1e-9).tolist(),
        elevation=rng.uniform(-0.1, 0.5, n).tolist(),
    )
    assert PlotBatch.from_json_bytes(b.to_json_bytes()) == b


# ---- other messages ----------------------------------------------------------------------
def test_radar_site_validation():
    s = RadarSite(radar_id="bgd", lat=44.82, lon=20.29, alt=120.0, kind="3d")
    assert RadarSite.from_json_bytes(s.to_json_bytes()) == s
    with pytest.raises(ValidationError, match="kind"):
        RadarSite(radar_id="x", lat=0, lon=0, kind="4d")
    with pytest.raises(ValidationError, match="lat"):
        RadarSite(radar_id="x", lat=91, lon=0, kind="2d")
    with pytest.raises(ValidationError, match="min_range"):
        RadarSite(radar_id="x", lat=0, lon=0, kind="2d", min_range=5e5, max_range=1e5)
    with pytest.raises(ValidationError, match="radar_id"):
        RadarSite(radar_id="a/b", lat=0, lon=0, kind="2d")
    with pytest.raises(ValidationError, match="sigma_range"):
        RadarSite(radar_id="x", lat=0, lon=0, kind="2d", sigma_range=-1)


def _track(**kw):
    d = dict(
        track_id=1,
        time=5,
        status="confirmed",
        existence=0.99,
        state=[1.0, 2.0, 3.0, 4.0],
        covariance=np.eye(4).tolist(),
        lat=44.0,
        lon=20.0,
        alt=3000.0,
        vel_east=1.0,
        vel_north=2.0,
        speed=2.236,
        heading=0.46,
        radars=["a", "b"],
        updates=7,
    )
    d.update(kw)
    return d


def test_track_batch_round_trip_and_checks():
    tb = TrackBatch(
        fusion_id="main",
        cycle=3,
        time=5,
        frame={"kind": "stereographic", "lat0": 44.0, "lon0": 20.0},
        state_labels=["x", "vx", "y", "vy"],
        tracks=[Track(**_track())],
    )
    assert TrackBatch.from_json_bytes(tb.to_json_bytes()) == tb
    with pytest.raises(ValidationError, match="covariance"):
        Track(**_track(covariance=np.eye(3).tolist()))
    with pytest.raises(ValidationError, match="existence"):
        Track(**_track(existence=1.5))
    with pytest.raises(ValidationError, match="state_labels"):
        TrackBatch(
            fusion_id="m",
            cycle=0,
            time=0,
            frame={"kind": "ned"},
            state_labels=["x", "y"],
            tracks=[Track(**_track())],
        )
    ev = TrackEvent(
        fusion_id="m", time=1, kind="merged", track_id=3, other_track_id=1, existence=0.5
    )
    assert TrackEvent.from_json_bytes(ev.to_json_bytes()) == ev


def test_truth_and_status():
    t = Truth(
        time=1,
        target_id=[1, 2],
        lat=[44.0, 45.0],
        lon=[20.0, 21.0],
        alt=[1e3, 2e3],
        vel_east=[1.0, 2.0],
        vel_north=[0.0, 1.0],
        vel_up=[0.0, 0.0],
    )
    assert Truth.from_json_bytes(t.to_json_bytes()) == t
    with pytest.raises(ValidationError, match="unique"):
        Truth(
            time=1,
            target_id=[1, 1],
            lat=[0, 0],
            lon=[0, 0],
            alt=[0, 0],
            vel_east=[0, 0],
            vel_north=[0, 0],
            vel_up=[0, 0],
        )
    with pytest.raises(ValidationError, match="has 1 values"):
        Truth(
            time=1,
            target_id=[1, 2],
            lat=[0],
            lon=[0, 0],
            alt=[0, 0],
            vel_east=[0, 0],
            vel_north=[0, 0],
            vel_up=[0, 0],
        )
    st_ = Status(
        service="fusion",
        service_id="main",
        time=1,
        uptime_s=2.0,
        counters={"plots": 5},
        rejected={"invalid PlotBatch": 1},
    )
    assert Status.from_json_bytes(st_.to_json_bytes()) == st_


def test_unknown_fields_are_rejected():
    with pytest.raises(ValidationError, match="extra"):
        PlotBatch(**make_batch(2), bogus=1)


# ---- key space -------------------------------------------------------------------------
def test_key_space_and_models():
    assert keys.radar_plots("r1") == "skyfuse/@v1/radar/r1/plots"
    assert keys.parse(keys.radar_site("r1")) == keys.KeyInfo("site", "r1")
    assert keys.parse(keys.fusion_tracks("main")) == keys.KeyInfo("tracks", "main")
    assert keys.parse(keys.SIM_TRUTH).kind == "truth"
    assert schemas.model_for_key(keys.radar_plots("x")) is PlotBatch
    assert schemas.model_for_key(keys.fusion_events("x")) is TrackEvent
    with pytest.raises(ValueError, match="key space"):
        keys.parse("skyfuse/@v2/radar/r1/plots")
    with pytest.raises(ValueError, match="not valid"):
        keys.radar_plots("a/b")
    with pytest.raises(ValueError, match="no message payload"):
        schemas.model_for_key(keys.radar_alive("r1"))


def test_json_schemas_written(tmp_path):
    from skyfuse.services.cli.cmd_schemas import write_schemas

    paths = write_schemas(tmp_path)
    names = {p.name for p in paths}
    assert {
        "PlotBatch.schema.json",
        "RadarSite.schema.json",
        "TrackBatch.schema.json",
        "Truth.schema.json",
        "Status.schema.json",
        "TrackEvent.schema.json",
        "keys.json",
    } <= names
    plot_schema = json.loads((tmp_path / "PlotBatch.schema.json").read_text())
    assert "range" in plot_schema["properties"]
    assert "m" in plot_schema["properties"]["range"]["description"]
