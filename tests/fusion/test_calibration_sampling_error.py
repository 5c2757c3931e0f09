"""Sampling error of the calibrated ψ_init (fusion.evaluation.calibration).

For a count that is an exact power law μ(ψ) = A ψ^b the elasticity is b and the
delta-method error is SE(log ψ*) = 1/(b √μ(ψ*)). A Monte Carlo of Poisson counts checks
that the interval covers the spread of ψ* that other run sets would give."""

from __future__ import annotations

import math

import numpy as np
import pytest
from skyfuse.fusion.evaluation import calibrate_psi_init
from skyfuse.fusion.evaluation.calibration import sampling_interval


@pytest.mark.parametrize("b", [0.5, 1.0, 2.0])
def test_power_law_elasticity_and_error(b):
    a = 15.0 / 0.01**b  # 15 false tracks at ψ = 0.01

    res = calibrate_psi_init(lambda psi: a * psi**b, 15.0, 1.5, psi0=0.04)
    d = res.as_dict()
    assert d["elasticity"] == pytest.approx(b, rel=1e-9)
    se = 1.0 / (b * math.sqrt(res.count))
    assert d["psi_se_log"] == pytest.approx(se, rel=1e-9)
    lo, hi = d["psi_interval_95"]
    assert lo == pytest.approx(res.psi_init * math.exp(-1.96 * se))
    assert hi == pytest.approx(min(res.psi_init * math.exp(1.96 * se), 1.0))


def test_unknown_slope_gives_no_interval():
    assert sampling_interval([(0.5, 0.0), (0.125, 0.0)], 0.5, 0.0)["psi_interval_95"] is None


def test_interval_covers_the_spread_of_poisson_calibrations():
    """ψ* solving Poisson count(ψ*) = 15 over independent run sets: the log-ψ* spread
    matches the delta-method SE within 25 % (μ = A ψ, b = 1)."""
    rng = np.random.default_rng(5)
    a = 15.0 / 0.01
    # for μ = a ψ, the calibrated ψ* from one Poisson draw n ≈ μ(ψ_true) is ψ_true·15/n
    n = rng.poisson(15.0, 20000)
    log_psi = np.log(0.01 * 15.0 / np.maximum(n, 1))
    res = calibrate_psi_init(lambda psi: a * psi, 15.0, 1.5)
    assert np.std(log_psi) == pytest.approx(res.as_dict()["psi_se_log"], rel=0.25)
