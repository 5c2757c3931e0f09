"""Registration fed by the tracker: ``observe_tracker_output`` takes the
plots confirmed tracks selected in ``Tracker.step`` — no truth — and the estimate of a
biased radar converges to the simulated bias within its stated uncertainty."""

from __future__ import annotations

import math

import numpy as np
from skyfuse.fusion.frames import SystemFrame, convert_plots
from skyfuse.fusion.registration import (
    RegistrationConfig,
    RegistrationEstimator,
    observe_tracker_output,
)
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig
from skyfuse.fusion.tracker.measurements import SectorCoverage


def _measurements(conv, site, batch) -> MeasurementBatch:
    ok = np.flatnonzero(conv.valid)
    cov = SectorCoverage(site=conv.site_position, min_range=site.min_range,
                         max_range=site.max_range, sector_start=batch.sector_start,
                         sector_width=batch.sector_width, time_start=batch.time_start,
                         time_end=batch.time_end)  # fmt: skip
    return MeasurementBatch(time_ns=batch.time_end, radar_id=site.radar_id, z=conv.z[ok],
                            R=conv.R[ok], p_detection=site.p_detection,
                            clutter_density=site.clutter_density, coverage=cov,
                            plot_times=conv.time[ok], plot_ids=ok)  # fmt: skip


def test_tracker_driven_estimate_recovers_azimuth_and_range_bias():
    sc = build_scenario("regional", seed=5, duration=240.0, targets=25, n_sectors=4,
                        **{"LYVR.bias_azimuth_deg": 0.3, "LYVR.bias_range_m": 200.0})  # fmt: skip
    sim = Simulator(sc)
    frame = SystemFrame.from_spec(sc.frame)
    sites = {s.radar_id: s for s in sc.sites}
    tracker = Tracker(TrackerConfig())
    est = RegistrationEstimator(RegistrationConfig(reference=["LYBE"], components=[
        "azimuth", "range", "range_gain"]))  # fmt: skip
    for ev in sim.run(truth=False):
        if ev.kind != "plots":
            continue
        site = sites[ev.message.radar_id]
        corr = est.correction(site.radar_id)
        conv = convert_plots(frame, site, ev.message, bias=corr)
        out = tracker.step(_measurements(conv, site, ev.message))
        observe_tracker_output(est, out, conv, tracker.vel)
    e = {x.radar_id: x for x in est.estimates()}
    lyvr = e["LYVR"]
    assert lyvr.pairs_used > 100
    truth = np.array([math.radians(0.3), 200.0])
    err = np.abs(lyvr.bias.vector()[:2] - truth)
    assert np.all(err < 4 * lyvr.sigma[:2]), lyvr.as_dict()
    assert lyvr.sigma[0] < math.radians(0.03) and lyvr.sigma[1] < 30.0
    assert lyvr.bias.time == 0.0 and lyvr.sigma[3] == 0.0  # not estimated: fixed at 0
    # the unbiased radars are consistent with zero
    for rid in ("LRTR", "NOVISAD"):
        x = e[rid]
        assert np.all(np.abs(x.bias.vector()[:2]) < 4 * x.sigma[:2]), x.as_dict()


def test_observe_tracker_output_selects_rows_consistently():
    """Plots of unconfirmed, single-radar or shared tracks and plots within
    min_ground_range of the radar are left out; the others reach the pair buffer with
    their own position, time and track velocity."""
    from types import SimpleNamespace as NS

    est = RegistrationEstimator(RegistrationConfig(reference=["a"], min_ground_range=10e3))
    k = 5
    z = np.array([[5e3, 0.0], [2e4, 0.0], [3e4, 1e3], [4e4, 0.0], [5e4, 0.0]])
    conv = NS(z=z, R=np.broadcast_to(np.eye(2), (k, 2, 2)), time=np.arange(k) * 10,
              polar_jacobian=np.ones((k, 2, 2)), slant_range=np.full(k, 1e4),
              site_position=np.zeros(2), radar_id="b", bias=None)  # fmt: skip
    # tracks: 0 near the radar, 1 fine, 2 tentative, 3 one radar only, 4 fine (plot 4)
    out = NS(ids=np.array([10, 11, 12, 13, 14]), assigned_plot=np.array([0, 1, 2, 3, 4]),
             confirmed=np.array([1, 1, 0, 1, 1], bool), radar_mask=np.array([3, 3, 3, 1, 3]),
             batch=NS(plot_ids=np.arange(k)),
             states=np.arange(20.0).reshape(5, 4), covariances=np.zeros((5, 4, 4)))  # fmt: skip
    observe_tracker_output(est, out, conv, np.array([1, 3]))
    store = est.pairs.store
    assert store.track.tolist() == [11, 14]
    np.testing.assert_array_equal(store.z, z[[1, 4]])
    assert store.time.tolist() == [10, 40]
    np.testing.assert_array_equal(store.v, out.states[[1, 4]][:, [1, 3]])
