"""Plots near the radar: where a 2-D radar's flight level and slant range
disagree (|sin e| ≥ 1) or the elevation is ill-conditioned, the plot is kept, projected
on the slant-range sphere with a covariance that covers the disagreement.

References: scipy.stats.truncnorm (closed-form truncated-normal moments), the exact
sphere geometry ρ² + u² = D², pymap3d (truth positions), and a Monte Carlo NEES."""

from __future__ import annotations

import numpy as np
import pymap3d
from scipy.stats import chi2, truncnorm
from skyfuse.fusion.frames import SystemFrame, convert_plots
from skyfuse.fusion.frames.polar import near_radar_moments
from skyfuse.schemas import PlotBatch, RadarSite

SITE = RadarSite(radar_id="bcn", lat=41.3007, lon=2.1021, alt=27.3, kind="2d",
                 sigma_range=50.0, sigma_azimuth=0.002, sigma_altitude=30.0)  # fmt: skip


def _batch(D, psi, h) -> PlotBatch:
    n = len(D)
    return PlotBatch(radar_id=SITE.radar_id, scan=0, seq=0, time_start=0, time_end=0,
                     time=[0] * n, range=[float(v) for v in D],
                     azimuth=[float(v) for v in np.mod(psi, 2 * np.pi)],
                     altitude=[float(v) for v in h])  # fmt: skip


def test_moments_match_the_truncated_normal_and_the_sphere():
    D = np.array([2000.0, 3000.0, 5000.0, 10_000.0, 800.0])
    u_m = np.array([2500.0, 2900.0, 4990.0, 9990.0, -900.0])
    sig = np.array([500.0, 100.0, 30.0, 60.0, 150.0])
    E_rho, E_u, var_rho, var_u, _ = near_radar_moments(D, u_m, sig)
    a, b = (-D - u_m) / sig, (D - u_m) / sig
    np.testing.assert_allclose(E_u, truncnorm.mean(a, b, loc=u_m, scale=sig), rtol=1e-6)
    np.testing.assert_allclose(var_u, truncnorm.var(a, b, loc=u_m, scale=sig), rtol=1e-5)
    # ρ² + u² = D² on the sphere: E[ρ²] = D² − E[u²]
    Eu2 = truncnorm.moment(2, a, b, loc=u_m, scale=sig)
    np.testing.assert_allclose(var_rho + E_rho**2, D**2 - Eu2, rtol=1e-6)
    assert np.all((E_rho >= 0) & (E_rho <= D))


def test_moments_reduce_to_the_delta_method_far_from_the_poles():
    D, u_m, sig = np.array([20_000.0]), np.array([5000.0]), np.array([40.0])
    E_rho, _, var_rho, _, _ = near_radar_moments(D, u_m, sig)
    rho = np.sqrt(D**2 - u_m**2)
    # second-order delta method: E ρ ≈ ρ − D² σ²/(2ρ³), Var ρ ≈ (u/ρ)² σ²
    np.testing.assert_allclose(E_rho, rho - D**2 * sig**2 / (2 * rho**3), atol=0.01)
    np.testing.assert_allclose(var_rho, (u_m / rho) ** 2 * sig**2, rtol=1e-3)


def test_impossible_flight_level_is_kept_over_the_radar():
    """FL puts the aircraft 3.2 km above a radar whose slant range says 3 km: kept, on
    the range sphere, the ground-range σ covering the possible positions."""
    frame = SystemFrame.ned(SITE.lat, SITE.lon, SITE.alt)
    c = convert_plots(frame, SITE, _batch([3000.0], [0.7], [SITE.alt + 3200.0]))
    assert c.valid.all() and c.n_near_radar == 1 and c.reasons == [""]
    rho = np.hypot(*c.z[0])
    assert rho < 3000.0
    # the disagreement (200 m) sets σ_u ≈ 208 m: u ∈ [2.6 km, 3 km] → ρ ∈ [0, 1.5 km]
    sig = np.sqrt(np.linalg.eigvalsh(c.R[0])).max()
    assert 250.0 < sig < 1500.0 and rho < 3 * sig
    # a nonsense range (not > 0) is the only rejection
    bad = convert_plots(frame, SITE, _batch([0.0], [0.7], [5000.0]))
    assert not bad.valid[0] and "must be > 0" in bad.reasons[0]


def _monte_carlo(n: int, seed: int):
    """Aircraft within 3 km ground range and 0.5-4 km above a radar; noisy D, ψ, h."""
    rng = np.random.default_rng(seed)
    rho = 3000.0 * np.sqrt(rng.random(n))
    az = rng.uniform(0, 2 * np.pi, n)
    up = rng.uniform(500.0, 4000.0, n)
    lat, lon, h = pymap3d.enu2geodetic(rho * np.sin(az), rho * np.cos(az), up,
                                       SITE.lat, SITE.lon, SITE.alt)  # fmt: skip
    a, _, sr = pymap3d.geodetic2aer(lat, lon, h, SITE.lat, SITE.lon, SITE.alt)
    D = sr + rng.normal(0, SITE.sigma_range, n)
    psi = np.radians(a) + rng.normal(0, SITE.sigma_azimuth, n)
    h_m = h + rng.normal(0, SITE.sigma_altitude, n)
    frame = SystemFrame.ned(SITE.lat, SITE.lon, SITE.alt)
    c = convert_plots(frame, SITE, _batch(D, psi, h_m))
    truth = np.stack(frame.from_geodetic(lat, lon, h), -1)[:, :2]
    d = c.z - truth
    nees = np.einsum("ki,ki->k", d, np.linalg.solve(c.R, d[..., None])[..., 0])
    return c, nees


def test_near_radar_plots_are_consistent_monte_carlo_nees():
    c, nees = _monte_carlo(4000, seed=11)
    assert c.valid.all()  # nothing rejected, including the |sin e| >= 1 ones
    near = c.near_radar
    assert near.sum() > 150
    # horizontal NEES of the near-radar plots: never above the 99.9 % band of a χ²₂ mean
    # (not overconfident), and at most 30 % under it (measured ≈ 1.5-1.65 against 2:
    # mildly conservative, from the range noise carried in σ_u and the flat prior on u)
    k = int(near.sum())
    lo, hi = chi2.ppf([0.0005, 0.9995], 2 * k) / k
    assert 0.7 * lo < nees[near].mean() < hi, nees[near].mean()
    # the far plots (linearised conversion) are consistent as before
    far = ~near
    lo, hi = chi2.ppf([0.0005, 0.9995], 2 * int(far.sum())) / int(far.sum())
    assert lo < nees[far].mean() < hi
    # and the 99 % gate holds ≈ 99 % of them (no heavy tail of overconfident plots)
    assert np.mean(nees[near] <= chi2.ppf(0.99, 2)) > 0.97
