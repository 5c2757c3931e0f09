"""PCRLB floor of the Monte Carlo evaluation (fusion.evaluation.bound, Tichavský et al. 1998).

References: the least-squares line fit (q = 0, diffuse prior: position variance
2σ²(2k − 1)/(k(k + 1)) per axis after k plots, scaled by 1/P_D with the information
reduction factor), the library's bound ``fusion.particles.pcrlb.linear_gaussian`` for a
hand-made truth, and the RMSE of a single clutter-free target tracked by the evaluation
itself, which must not fall below its floor beyond Monte Carlo error."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.evaluation import Experiment, VariantRunner, summarise
from skyfuse.fusion.evaluation.bound import (
    PRIOR_VARIANCE,
    pcrlb_curves,
    position_bound_by_age,
    truth_ages,
)
from skyfuse.fusion.metrics.history import TrackHistory, TruthHistory
from skyfuse.fusion.models import ConstantVelocity
from skyfuse.fusion.particles import pcrlb


@pytest.mark.parametrize("pd", [1.0, 0.8])
def test_straight_line_bound_is_the_least_squares_fit(pd):
    k = np.arange(1, 21)
    closed = 2 * 25.0 * 2 * (2 * k - 1) / (k * (k + 1)) / pd
    got = position_bound_by_age(20, 1.0, 0.0, 25.0, pd)
    assert np.allclose(got, closed, rtol=1e-5)


def _hand_made():
    """Two runs; run 0: target 0 at scans 1..6, target 1 born at scan 3 (to 6); run 1:
    target 0 at scans 2..5. Tracks: confirmed true rows on some of them, one false row."""
    rows = [(0, s, 0) for s in range(1, 7)] + [(0, s, 1) for s in range(3, 7)]
    rows += [(1, s, 0) for s in range(2, 6)]
    run, scan, tid = (np.array(c) for c in zip(*rows, strict=True))
    truth = TruthHistory(run, scan, tid, np.zeros((len(run), 2)))
    # (run, scan, track id, confirmed, label)
    t = [(0, 4, 10, 1, 0), (0, 5, 10, 1, 0), (0, 6, 10, 1, 0), (0, 5, 11, 1, 1),
         (0, 6, 11, 1, 1), (0, 6, 12, 0, 1), (0, 6, 13, 1, -1), (1, 5, 20, 1, 0)]  # fmt: skip
    r, s, i, c, lab = (np.array(x) for x in zip(*t, strict=True))
    tracks = TrackHistory(r, s, i, c.astype(bool), lab, np.zeros((len(r), 2)), np.ones(len(r)))
    return truth, tracks


def test_curves_equal_the_library_bound_for_a_hand_made_truth():
    truth, tracks = _hand_made()
    assert truth_ages(truth).tolist() == [1, 2, 3, 4, 5, 6, 1, 2, 3, 4, 1, 2, 3, 4]
    q, s2, pd = 0.75, 25.0, 0.8
    cv = ConstantVelocity(q=q, ndim=2)
    P = pcrlb.linear_gaussian(
        PRIOR_VARIANCE * np.eye(4), cv.F(1.0), cv.Q(1.0), cv.H(), s2 * np.eye(2), 6,
        information_factor=pd,
    )  # fmt: skip
    B = P[:, 0, 0] + P[:, 2, 2]  # position block of [x, vx, y, vy]
    scans = np.arange(1, 7)
    floor, floor_all = pcrlb_curves(tracks, truth, scans, position_bound_by_age(6, 1.0, q, s2, pd))
    # rows of the RMSE: confirmed, labelled true, target present
    expect = [np.nan, np.nan, np.nan, B[3], (B[4] + B[2] + B[3]) / 3, (B[5] + B[3]) / 2]
    assert np.allclose(floor**2, expect, rtol=1e-9, equal_nan=True)
    expect_all = [B[0], (B[1] + B[0]) / 2, (B[2] + B[0] + B[1]) / 3]
    expect_all += [(B[3] + B[1] + B[2]) / 3, (B[4] + B[2] + B[3]) / 3, (B[5] + B[3]) / 2]
    assert np.allclose(floor_all**2, expect_all, rtol=1e-9)


def test_bound_longer_than_the_truth_is_required():
    truth, tracks = _hand_made()
    with pytest.raises(ValueError, match="age 6"):
        pcrlb_curves(tracks, truth, np.arange(1, 7), np.ones(5))


def test_single_target_rmse_stays_above_its_floor():
    """thesis-stt without clutter (truth q = 0.75, P_D = 0.6, σ = 5 m), IPDA with the
    source settings, 40 runs. Per scan the squared error of n independent rows (one per
    run) has a relative standard error ≈ 1/√n (2-D Gaussian error: ‖e‖² ~ m·Exp(1)), so
    RMSE² ≥ floor² (1 − 3/√n) at every scan with n ≥ 5 rows."""
    exp = Experiment(
        scenario="thesis-stt",
        scenario_params={"weak_density": 0.0, "strong_density": 0.0},
        trackers=["ipda"],
        runs=40,
        seed=3,
    )
    v = exp.variants()[0]
    s = summarise(VariantRunner(exp, v).run_many(range(exp.runs)), exp, v, exp.psi_for(v))
    c = s["curves"]
    assert c["pcrlb_model"] == {
        "q": 0.75, "sigma2": 25.0, "p_detection": 0.6, "period": 1.0,
        "prior_variance": PRIOR_VARIANCE,
    }  # fmt: skip
    n = np.array(c["rmse_rows"])
    use = n >= 5
    assert use.sum() >= 30
    rmse = np.array([np.nan if x is None else x for x in c["rmse_m"]])[use]
    floor = np.array([np.nan if x is None else x for x in c["pcrlb_m"]])[use]
    assert np.all(rmse**2 >= floor**2 * (1 - 3 / np.sqrt(n[use])))
    # the floor is the steady state of the ERC recursion once tracks are confirmed
    steady = position_bound_by_age(50, 1.0, 0.75, 25.0, 0.6)[-1]
    assert np.allclose(floor[-10:] ** 2, steady, rtol=1e-3)  # JSON rounds to 1 mm
