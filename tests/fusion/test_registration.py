"""Online registration: on a synthetic two-radar case (regional scenario,
the Beograd radar as reference, Vršac biased) the estimator recovers the simulated
biases within its stated uncertainty, and gives estimates consistent with zero for an
unbiased radar. Associations come from the simulator's target ids and velocities from
the truth, so the test checks the estimator alone (the tracker-driven case is
benchmarks/registration.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from skyfuse.fusion.frames import SystemFrame, convert_plots
from skyfuse.fusion.registration import RegistrationConfig, RegistrationEstimator
from skyfuse.fusion.sim import Simulator, build_scenario

RADARS = ("LYBE", "LYVR")


def _run(bias: dict, *, duration: float = 480.0, mode: str = "on", seed: int = 3):
    params = {f"LYVR.{k}": v for k, v in bias.items()}
    sc = build_scenario("regional", seed=seed, duration=duration, targets=30, radars=3,
                        n_sectors=1, clutter_density=0.0, ground_clutter_density=0.0,
                        **params)  # fmt: skip
    frame = SystemFrame.from_spec(sc.frame)
    sites = {s.radar_id: s for s in sc.sites}
    est = RegistrationEstimator(RegistrationConfig(reference=["LYBE"], mode=mode))
    sim = Simulator(sc)
    for scan in sim.scans():
        if scan.radar_id not in RADARS:
            continue
        for batch in sim.sector_batches(scan, 0):
            bias_used = est.correction(batch.radar_id)
            conv = convert_plots(frame, sites[batch.radar_id], batch, bias=bias_used)
            tid = batch.column("target_id")
            k = np.flatnonzero(conv.valid & (tid >= 0))
            if not len(k):
                continue
            truth = sim.truth_at(conv.time[k], geodetic=False)
            col = np.searchsorted(truth["target_id"], tid[k])
            v = np.stack([truth["vx"][np.arange(len(k)), col],
                          truth["vy"][np.arange(len(k)), col]], axis=-1)  # fmt: skip
            Pvv = np.broadcast_to(25.0 * np.eye(2), (len(k), 2, 2))
            c = (conv.time[k], conv.z[k], conv.R[k], conv.polar_jacobian[k], conv.slant_range[k])
            est.observe_plots(batch.radar_id, tid[k], *c, v, Pvv, bias_used)
    return {e.radar_id: e for e in est.estimates()}, est


TRUE = {"bias_azimuth_deg": 0.2, "bias_range_m": 150.0, "bias_time_ms": 50.0}


def _truth_vector(bias: dict) -> np.ndarray:
    return np.array([
        math.radians(bias.get("bias_azimuth_deg", 0.0)), bias.get("bias_range_m", 0.0),
        bias.get("bias_range_gain_ppm", 0.0) * 1e-6, bias.get("bias_time_ms", 0.0) * 1e-3,
    ])  # fmt: skip


GAIN = {"bias_range_gain_ppm": 1000.0, "bias_range_m": -100.0}


@pytest.mark.parametrize("bias", [TRUE, GAIN, {}], ids=["biased", "gain", "unbiased"])
def test_estimates_within_stated_uncertainty(bias):
    est, _ = _run(bias)
    e = est["LYVR"]
    assert e.pairs_used > 200
    z = (e.bias.vector() - _truth_vector(bias)) / e.sigma
    assert np.all(np.abs(z) < 3.5), (e.as_dict(), z)
    # informative: azimuth and range offset resolved far below the simulated biases
    assert e.sigma[0] < math.radians(0.03) and e.sigma[1] < 30.0
    ref = est["LYBE"]
    assert ref.reference and not ref.bias.vector().any() and not ref.sigma.any()


def test_frozen_and_off_modes():
    est, reg = _run(TRUE, duration=60.0, mode="frozen")
    assert est["LYVR"].pairs_used == 0 and est["LYVR"].bias.is_zero
    assert reg.correction("LYVR").is_zero
    reg.set_mode("off")
    assert reg.correction("LYVR") is None


def test_non_finite_rows_are_counted_not_used():
    reg = RegistrationEstimator(RegistrationConfig(reference=["a"]))
    k = 3
    z = np.array([[1e4, 2e4], [np.nan, 0.0], [3e4, 1e4]])
    R = np.broadcast_to(100.0 * np.eye(2), (k, 2, 2)).copy()
    J = np.broadcast_to(np.array([[0.5, 1e4], [0.8, -2e4]]), (k, 2, 2)).copy()
    v = np.array([[100.0, 0.0], [0.0, 100.0], [np.inf, 0.0]])
    P = np.broadcast_to(np.eye(2), (k, 2, 2)).copy()
    reg.observe_plots("a", np.arange(k), np.arange(k) * 10**9, z, R, J, np.full(k, 3e4), v,
                      P, None)  # fmt: skip
    n = reg.observe_plots("b", np.arange(k), np.arange(k) * 10**9 + 10**8, z, R, J,
                          np.full(k, 3e4), v, P, None)  # fmt: skip
    assert reg.skipped == 4 and n == 1  # only track 0 forms a pair
    assert reg.status()["plots_not_finite"] == 4
