"""Radar registration against ADS-B: on a simulated scenario with three radars and an
ADS-B network, one radar biased in azimuth and range, the online registration with the
ADS-B as its only reference (``reference = ["ADSB"]``: every radar estimated) brings each
radar's estimate to the simulated truth within its own σ — with and without the
exclusion of poor ADS-B reports (``max_reference_sigma``). Poor reports whose positions
are wrong beyond what their σ says (injected here: moved 300 m east, a degraded position
source) bias the estimate when they are used and not when they are excluded.

The truth is the scenario's bias parameters (fusion.sim.site_bias), never told to the
tracker; the check is |β̂ − β| ≤ 3.5 σ̂ per component (σ̂ the filter's own), with σ̂
small enough for the check to mean something.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from skyfuse.fusion.registration import RegistrationConfig, RegistrationEstimator
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.fusion.tracker import TrackerConfig
from skyfuse.schemas import PlotBatch
from skyfuse.services.evaluation.offline import OfflineConfig, run_offline

BIAS_AZ_DEG, BIAS_RANGE = 0.2, 150.0
SHIFT_EAST = 250.0


@pytest.fixture(scope="module")
def messages():
    sc = build_scenario(
        "regional", seed=4, duration=360.0, targets=30, radars=3, n_sectors=4, adsb=True,
        adsb_poor_fraction=0.5, adsb_poor_nacp=7, adsb_equipped_fraction=0.9, clutter_density=0.0,
        ground_clutter_density=0.0, **{"LYVR.bias_azimuth_deg": BIAS_AZ_DEG,
                                       "LYVR.bias_range_m": BIAS_RANGE},
    )  # fmt: skip
    return [ev.message for ev in Simulator(sc).run(truth=False)]


def _inject(messages):
    """The poor ADS-B reports (NACp 7: σ 75.6 m) moved 250 m east."""
    out = []
    for m in messages:
        if isinstance(m, PlotBatch) and m.radar_id == "ADSB" and len(m):
            poor = m.column("sigma") > 50.0
            lat, lon = m.column("lat"), m.column("lon").copy()
            lon[poor] += SHIFT_EAST / (111_320.0 * np.cos(np.radians(lat[poor])))
            m = m.model_copy(update={"lon": lon.tolist()})
        out.append(m)
    return out


def _estimates(messages, max_sigma):
    reg = RegistrationConfig(reference=["ADSB"], components=["azimuth", "range"],
                             max_reference_sigma=max_sigma)  # fmt: skip
    cfg = OfflineConfig(tracker=TrackerConfig(), registration=reg)
    est = run_offline(messages, None, cfg).pipeline.registration.estimator
    return {e.radar_id: e for e in est.estimates()}, est


def _errors(estimates):
    """{radar: (azimuth error / σ, range error / σ)} against the simulated truth."""
    out = {}
    for rid in ("LYBE", "LYVR", "LRTR"):
        e = estimates[rid]
        truth = (math.radians(BIAS_AZ_DEG), BIAS_RANGE) if rid == "LYVR" else (0.0, 0.0)
        v = e.bias.vector()
        out[rid] = tuple((v[i] - truth[i]) / e.sigma[i] for i in (0, 1))
        assert not e.reference and e.pairs_used > 100, (rid, e.pairs_used)
        assert e.sigma[0] < math.radians(0.02) and e.sigma[1] < 15.0, (rid, e.sigma)
    return out


@pytest.mark.parametrize("max_sigma", [None, 40.0])
def test_radar_biases_converge_to_truth_against_adsb(messages, max_sigma):
    estimates, est = _estimates(messages, max_sigma)
    assert estimates["ADSB"].reference
    for rid, z in _errors(estimates).items():
        assert max(abs(x) for x in z) < 3.5, (rid, z)
    assert (est.reference_excluded > 0) == (max_sigma is not None)


def test_excluded_poor_reports_do_not_bias_the_estimate(messages):
    shifted = _inject(messages)
    estimates, est = _estimates(shifted, 40.0)
    assert est.reference_excluded > 1000
    copy = RegistrationEstimator(est.cfg)  # the count is declared state, in the snapshot
    copy.from_snapshot(est.to_snapshot())
    assert copy.reference_excluded == est.reference_excluded and copy.status() == est.status()
    for rid, z in _errors(estimates).items():
        assert max(abs(x) for x in z) < 3.5, (rid, z)
    # the same reports used: the radars are registered onto the shifted positions
    biased = _errors(_estimates(shifted, None)[0])
    assert max(abs(x) for z in biased.values() for x in z) > 5.0, biased
