"""``skyfuse track`` end to end on a small hand-made recording (cartesian sensor, two
straight targets, light clutter, truth), plus TOML configuration and bad input."""

from __future__ import annotations

import json

import numpy as np
import pymap3d
import pytest
from skyfuse.schemas import PlotBatch, RadarSite, TrackBatch, TrackEvent, TrackPicture, Truth, keys
from skyfuse.services.cli.main import main
from skyfuse.services.recording.mcap_io import RecordingWriter, iter_recording

T0 = 1_767_225_600 * 10**9
LAT, LON = 45.0, 20.0


def make_recording(path, scans=25, seed=1):
    rng = np.random.default_rng(seed)
    site = RadarSite(
        radar_id="cart",
        lat=LAT,
        lon=LON,
        alt=0.0,
        kind="cartesian",
        sigma_cartesian=5.0,
        p_detection=0.9,
        clutter_density=1e-7,
        scan_period=1.0,
        max_range=20_000.0,
    )
    x0 = np.array([[-1000.0, 1000.0], [500.0, -800.0]])
    v = np.array([[30.0, -10.0], [-20.0, 25.0]])
    with RecordingWriter(path) as w:
        w.write(keys.radar_site("cart"), site, T0)
        for k in range(1, scans + 1):
            t = T0 + k * 10**9
            pos = x0 + v * k
            det = rng.random(2) < 0.9
            z = pos[det] + rng.normal(0, 5, (det.sum(), 2))
            clutter = rng.uniform(-3000, 3000, (rng.poisson(3), 2))
            allz = np.vstack([z, clutter])
            tid = [int(i) for i in np.flatnonzero(det)] + [-1] * len(clutter)
            w.write(
                keys.radar_plots("cart"),
                PlotBatch(
                    radar_id="cart",
                    scan=k,
                    seq=k,
                    time_start=t - 10**9,
                    time_end=t,
                    time=[t] * len(allz),
                    x=allz[:, 0].tolist(),
                    y=allz[:, 1].tolist(),
                    target_id=tid,
                ),
                t,
            )
            lat, lon, alt = pymap3d.enu2geodetic(pos[:, 0], pos[:, 1], 0 * pos[:, 0], LAT, LON, 0)
            w.write(
                keys.SIM_TRUTH,
                Truth(
                    time=t,
                    target_id=[0, 1],
                    lat=list(lat),
                    lon=list(lon),
                    alt=list(alt),
                    vel_east=list(v[:, 0]),
                    vel_north=list(v[:, 1]),
                    vel_up=[0.0, 0.0],
                ),
                t,
            )
    return x0, v


def test_track_command_writes_tracks_events_and_summary(tmp_path, capsys):
    rec, out, js = tmp_path / "r.mcap", tmp_path / "t.mcap", tmp_path / "t.json"
    x0, v = make_recording(rec)
    code = main(
        [
            "track",
            str(rec),
            "--tracker",
            "lmits",
            "--depth",
            "2",
            "--q",
            "1",
            "--v-max",
            "60",
            "--psi-init",
            "0.05",
            "--out",
            str(out),
            "--json",
            str(js),
        ]
    )
    assert code == 0
    s = json.loads(js.read_text())
    assert s["batches"] == 25 and s["plots_processed"] > 40
    lab, truth = s["labels"], s["truth"]
    assert lab["kind"] == "target_id"
    assert lab["aircraft"] == 2 and lab["aircraft_with_confirmed_track"] == 2
    assert lab["confirmed_false_tracks"] == 0
    assert truth["coverage"] > 0.7 and truth["position_rmse_m"] < 15
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["batches"] == 25
    batches = [r.message for r in iter_recording(out) if isinstance(r.message, TrackBatch)]
    events = [r.message for r in iter_recording(out) if isinstance(r.message, TrackEvent)]
    assert len(batches) == 25 and {e.kind.value for e in events} == {"confirmed"}
    picture = TrackPicture()  # the MCAP holds the feed's deltas: rebuild the picture
    for b in batches:
        picture.apply(b)
    assert picture.complete
    last = picture.batch()
    assert len(last.tracks) == 2 and last.state_labels == ["x", "vx", "y", "vy"]
    for tr in last.tracks:  # truth at the track's own time (its last update)
        pos = x0 + v * (25 + (tr.time - batches[-1].time) / 1e9)
        lat, lon, _ = pymap3d.enu2geodetic(pos[:, 0], pos[:, 1], 0 * pos[:, 0], LAT, LON, 0)
        d = [
            np.hypot(*pymap3d.geodetic2enu(tr.lat, tr.lon, 0, la, lo, 0)[:2])
            for la, lo in zip(lat, lon)
        ]
        i = int(np.argmin(d))
        assert d[i] < 20
        assert tr.speed == pytest.approx(np.hypot(*v[i]), abs=3)
        assert tr.vel_east == pytest.approx(v[i][0], abs=3)
        assert tr.radars == ["cart"] and tr.status.value == "confirmed"


def test_track_command_reads_tracker_toml(tmp_path):
    rec, out, js = tmp_path / "r.mcap", tmp_path / "t.mcap", tmp_path / "t.json"
    make_recording(rec, scans=6)
    toml = tmp_path / "c.toml"
    toml.write_text('[tracker]\ntracker = "jipda"\nq = 1.0\nv_max = 60.0\n')
    assert (
        main(["track", str(rec), "--config", str(toml), "--out", str(out), "--json", str(js)]) == 0
    )
    s = json.loads(js.read_text())
    assert s["tracker"] == "jipda" and s["config"]["v_max"] == 60.0


def test_track_command_bad_configuration_is_exit_2(tmp_path, capsys):
    rec = tmp_path / "r.mcap"
    make_recording(rec, scans=2)
    assert (
        main(["track", str(rec), "--tau-terminate", "0.99", "--out", str(tmp_path / "t.mcap")]) == 2
    )
    assert "tau_terminate" in capsys.readouterr().err
    assert main(["track", str(tmp_path / "missing.mcap")]) == 2


def test_adapter_builds_sector_coverage_and_counts_invalid_plots():
    from skyfuse.fusion.frames import SystemFrame, convert_plots
    from skyfuse.services.fusion.adapter import measurement_batch_from

    site = RadarSite(
        radar_id="r2",
        lat=LAT,
        lon=LON,
        alt=100.0,
        kind="2d",
        p_detection=0.8,
        clutter_density=2e-9,
        max_range=150_000.0,
    )
    t = T0 + 4 * 10**9
    batch = PlotBatch(
        radar_id="r2",
        scan=1,
        seq=3,
        sector_start=1.0,
        sector_width=0.5,
        time_start=t - 250_000_000,
        time_end=t,
        time=[t - 10**8, t - 10**7],
        range=[50_000.0, 60_000.0],
        azimuth=[1.2, 1.4],
        altitude=[9000.0, None],
        target_id=[7, -1],
    )
    frame = SystemFrame.stereographic(LAT, LON)
    mb = measurement_batch_from(convert_plots(frame, site, batch), site, batch)
    assert len(mb) == 1 and sum(mb.rejected.values()) == 1
    assert mb.p_detection == 0.8 and mb.clutter_density == 2e-9 and mb.time_ns == t
    assert list(mb.target_ids) == [7] and list(mb.plot_ids) == [0]
    cov = mb.coverage
    # the plot lies inside the swept sector and was swept ~60 % of the way through it
    assert cov.contains(mb.z)[0]
    assert cov.illumination_time(mb.z)[0] == pytest.approx(t - 250_000_000 + 0.4 * 250e6, abs=2e7)
    east, north = 50_000 * np.sin(0.5), 50_000 * np.cos(0.5)  # azimuth 0.5 rad: outside
    assert not cov.contains(np.array([[east, north]]))[0]
