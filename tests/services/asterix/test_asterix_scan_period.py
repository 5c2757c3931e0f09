"""Scan period estimated from plot times and azimuths, against the simulated truth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from skyfuse.services.asterix import estimate_scan_period


def rotating_radar_plots(period, n, duration, seed, sigma_az=0.002):
    """Targets at random azimuths; each plot is timed when the beam points at it."""
    rng = np.random.default_rng(seed)
    scan = rng.integers(0, int(duration / period), n)
    az_true = rng.uniform(0, 2 * math.pi, n)
    t = 100.0 + (scan + az_true / (2 * math.pi)) * period
    az = (az_true + rng.normal(0, sigma_az, n)) % (2 * math.pi)
    return t, az


@pytest.mark.parametrize(
    ("period", "n", "duration"),
    [(4.0, 2000, 600.0), (4.8, 300, 120.0), (12.0, 40, 300.0), (1.0, 500, 60.0)],
)
def test_recovers_the_period(period, n, duration):
    t, az = rotating_radar_plots(period, n, duration, seed=int(period * 10))
    est = estimate_scan_period(t, az)
    assert est is not None
    assert est[0] == pytest.approx(period, rel=2e-3)
    assert est[1] > 0.9


def test_no_rotation_no_estimate():
    rng = np.random.default_rng(7)
    t = np.sort(rng.uniform(0, 200, 400))
    assert estimate_scan_period(t, rng.uniform(0, 2 * math.pi, 400)) is None
    assert estimate_scan_period(t[:5], t[:5]) is None
