"""Radar polar measurements → local ENU at the radar, with covariance ([Dikić] eq. 7, 11-12).

Conventions: slant range D (m); azimuth ψ clockwise from north (rad); elevation θ
above the local horizontal (rad). Local ENU at the site:

    e = D cosθ sinψ,   n = D cosθ cosψ,   u = D sinθ

([Dikić] eq. 7a-c with x north, y east; here written east-first.) The covariance of a
converted plot is R = J R_s Jᵀ with the analytic Jacobian J = ∂(e,n,u)/∂(D,ψ,θ)
([Dikić] eq. 11-12, reordered east-first). For a 2-D radar the third measured quantity is
the target height h (Mode C / flight level) instead of θ; θ(D, h) is solved on a
sphere of local radius R ([LIT]) and its derivatives enter J.

Debiased ("unbiased converted measurement", Lerro & Bar-Shalom 1993; Mo Longbin et al.
1998) conversion divides out E[cos w] = λ = e^{−σ²/2} of the angle errors and uses the
measurement-conditioned covariance R = Cov[p | z] + (p_u − E[p | z])(p_u − E[p | z])ᵀ,
computed here from exact trigonometric moments of Gaussian angles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def spherical_to_enu(D, psi, theta) -> np.ndarray:
    """(D, ψ, θ) → (m, 3) east, north, up, metres."""
    D, psi, theta = np.broadcast_arrays(*(np.asarray(a, float) for a in (D, psi, theta)))
    ct = np.cos(theta)
    return np.stack([D * ct * np.sin(psi), D * ct * np.cos(psi), D * np.sin(theta)], axis=-1)


def spherical_jacobian(D, psi, theta) -> np.ndarray:
    """J = ∂(e, n, u)/∂(D, ψ, θ), shape (m, 3, 3) ([Dikić] eq. 11, east-first)."""
    D, psi, theta = np.broadcast_arrays(*(np.asarray(a, float) for a in (D, psi, theta)))
    sp, cp, st, ct = np.sin(psi), np.cos(psi), np.sin(theta), np.cos(theta)
    J = np.empty((*D.shape, 3, 3))
    J[..., 0, :] = np.stack([ct * sp, D * ct * cp, -D * st * sp], axis=-1)
    J[..., 1, :] = np.stack([ct * cp, -D * ct * sp, -D * st * cp], axis=-1)
    J[..., 2, :] = np.stack([st, np.zeros_like(D), D * ct], axis=-1)
    return J


@dataclass(frozen=True)
class ElevationSolution:
    """Elevation of a 2-D radar plot from its altitude.

    ``sin_theta`` may fall outside [−1, 1] when the geometry is impossible (slant range
    shorter than the height difference); ``feasible`` flags those plots."""

    theta: np.ndarray
    sin_theta: np.ndarray
    dtheta_dD: np.ndarray
    dtheta_dh: np.ndarray
    feasible: np.ndarray


def elevation_from_altitude(D, h_target, h_site, earth_radius) -> ElevationSolution:
    """Solve sinθ = ((R+h_T)² − (R+h_R)² − D²) / (2 (R+h_R) D) on a sphere of radius R
    ([LIT]); ``earth_radius=np.inf`` gives the flat-Earth sinθ = (h_T − h_R)/D.

    Returns θ (rad) and ∂θ/∂D (rad/m), ∂θ/∂h_T (rad/m) for the covariance Jacobian.
    Use ``earth_radius = k·R_α`` with k = 4/3 for the standard refraction model."""
    D = np.asarray(D, float)
    hT = np.asarray(h_target, float)
    R = np.asarray(earth_radius, float)
    D, hT, R = np.broadcast_arrays(D, hT, R)
    with np.errstate(divide="ignore", invalid="ignore"):
        flat = np.isinf(R)
        a = np.where(flat, 1.0, R + h_site)
        b = np.where(flat, 1.0, R + hT)
        dh = hT - h_site
        s_sphere = (dh * (b + a) - D * D) / (2.0 * a * D)  # (b² − a²) = (b − a)(b + a)
        s = np.where(flat, dh / D, s_sphere)
        ds_dD = np.where(flat, -dh / (D * D), -(dh * (b + a)) / (2 * a * D * D) - 1.0 / (2 * a))
        ds_dh = np.where(flat, 1.0 / D, b / (a * D))
        feasible = np.isfinite(s) & (np.abs(s) < 1.0) & (D > 0)
        s_clip = np.clip(s, -1.0, 1.0)
        theta = np.arcsin(s_clip)
        c = np.sqrt(np.maximum(1.0 - s_clip * s_clip, 1e-300))
    return ElevationSolution(theta, s, ds_dD / c, ds_dh / c, feasible)


def _trig_moments(mean, sigma):
    """Exact moments of cos/sin of a Gaussian angle N(mean, σ²):
    E[cos], E[sin], E[cos²], E[sin²], E[sin cos]."""
    lam = np.exp(-0.5 * sigma * sigma)
    lam4 = lam**4  # e^{−2σ²}
    c, s = np.cos(mean), np.sin(mean)
    c2m, s2m = np.cos(2 * mean), np.sin(2 * mean)
    return (
        lam * c,
        lam * s,
        0.5 * (1.0 + lam4 * c2m),
        0.5 * (1.0 - lam4 * c2m),
        0.5 * lam4 * s2m,
    )


def debiased_enu(
    rho, u, C_rho_u, psi, sigma_psi, *, lam_vertical=None, moments_vertical=None
) -> tuple[np.ndarray, np.ndarray]:
    """Debiased ENU position and measurement-conditioned covariance from horizontal range ρ,
    up u, azimuth ψ ([LIT] Mo Longbin et al. 1998, generalised to 3-D).

    ``rho, u``: measured horizontal range and height above the site plane, (m,);
    ``C_rho_u``: (m, 2, 2) covariance of (ρ, u) when they are (nearly) linear in the
    measurement (2-D radars); for 3-D radars pass ``moments_vertical`` instead — a
    tuple (E[ρ], E[u], E[ρ²], E[ρu], E[u²]) of the exact conditional moments — and
    ``lam_vertical`` = e^{−σ_θ²/2} to divide out of the measured (ρ, u).
    ``sigma_psi``: azimuth standard deviation, rad."""
    Ec, Es, Ecc, Ess, Esc = _trig_moments(psi, sigma_psi)
    lam = np.exp(-0.5 * sigma_psi**2)
    if moments_vertical is None:
        E_rho, E_u = rho, u
        E_rr = rho * rho + C_rho_u[..., 0, 0]
        E_ru = rho * u + C_rho_u[..., 0, 1]
        E_uu = u * u + C_rho_u[..., 1, 1]
        rho_u, u_u = rho, u
    else:
        E_rho, E_u, E_rr, E_ru, E_uu = moments_vertical
        rho_u, u_u = rho / lam_vertical, u / lam_vertical
    mean = np.stack([E_rho * Es, E_rho * Ec, E_u], axis=-1)
    second = np.empty((*np.shape(rho), 3, 3))
    second[..., 0, 0] = E_rr * Ess
    second[..., 1, 1] = E_rr * Ecc
    second[..., 0, 1] = second[..., 1, 0] = E_rr * Esc
    second[..., 0, 2] = second[..., 2, 0] = E_ru * Es
    second[..., 1, 2] = second[..., 2, 1] = E_ru * Ec
    second[..., 2, 2] = E_uu
    cov = second - mean[..., :, None] * mean[..., None, :]
    p_u = np.stack([rho_u * np.sin(psi) / lam, rho_u * np.cos(psi) / lam, u_u], axis=-1)
    d = p_u - mean
    R = cov + d[..., :, None] * d[..., None, :]
    return p_u, 0.5 * (R + np.swapaxes(R, -1, -2))


def vertical_moments_3d(D, sigma_D, theta, sigma_theta):
    """Exact conditional moments (E[ρ], E[u], E[ρ²], E[ρu], E[u²]) of ρ = D cosθ, u = D sinθ
    for independent Gaussian D ~ N(D_m, σ_D²), θ ~ N(θ_m, σ_θ²) (3-D radar debiasing)."""
    Ec, Es, Ecc, Ess, Esc = _trig_moments(theta, sigma_theta)
    ED2 = D * D + sigma_D * sigma_D
    return D * Ec, D * Es, ED2 * Ecc, ED2 * Esc, ED2 * Ess


_NEAR_NODES = 48
_NEAR_SPAN = 8.0  # integrate the Gaussian of u over ±8σ (inside the sphere)


def near_radar_moments(D, u_m, sigma_u):
    """Moments of (ρ, u) for a plot whose height disagrees with its slant range or
    whose elevation is ill-conditioned (close to or over the radar).

    The point lies on the sphere of radius D about the radar (e² + n² + u² = D², local
    ENU), so u ∈ [−D, D] and ρ = √(D² − u²). The height measurement says u ≈ u_m
    (u_m = D sinθ of :func:`elevation_from_altitude`, unclipped, may exceed D) with
    standard deviation σ_u. The posterior of u is N(u_m, σ_u²) truncated to [−D, D]
    (a flat prior on the sphere's height), and the moments E[u], E[u²], E[ρ], E[ρ²],
    E[ρu] follow by Gauss–Legendre quadrature over φ with u = D sin φ, ρ = D cos φ
    (smooth in φ, so the √ at the poles costs nothing), restricted to u_m ± 8σ_u.
    E[u] and E[u²] are those of the truncated normal (closed form, scipy.stats.truncnorm)
    and E[ρ²] = D² − E[u²] exactly.

    Returns (E[ρ], E[u], Var ρ, Var u, Cov(ρ, u)), each (m,), m and m²."""
    D, u_m, sig = np.broadcast_arrays(*(np.asarray(a, float) for a in (D, u_m, sigma_u)))
    top = 1.0 - 1e-12
    lo = np.clip((u_m - _NEAR_SPAN * sig) / D, -1.0, top)
    hi = np.clip((u_m + _NEAR_SPAN * sig) / D, -top, 1.0)
    lo = np.minimum(lo, hi - 1e-12)
    phi_lo, phi_hi = np.arcsin(lo), np.arcsin(hi)
    x, w = np.polynomial.legendre.leggauss(_NEAR_NODES)
    half = 0.5 * (phi_hi - phi_lo)[..., None]
    phi = 0.5 * (phi_hi + phi_lo)[..., None] + half * x
    u = D[..., None] * np.sin(phi)
    rho = D[..., None] * np.cos(phi)
    z2 = ((u - u_m[..., None]) / sig[..., None]) ** 2
    # weight: Gaussian density of u times du = ρ dφ (constant factors cancel; the
    # smallest exponent is taken out so that a far tail does not underflow)
    wt = w * half * rho * np.exp(-0.5 * (z2 - z2.min(axis=-1, keepdims=True)))
    norm = wt.sum(axis=-1)
    pole = norm <= 0.0  # the window shrank onto a pole (ρ = 0 at every node)
    norm = np.where(pole, 1.0, norm)

    def E(f):
        return (wt * f).sum(axis=-1) / norm

    E_u, E_rho = np.where(pole, np.sign(u_m) * D, E(u)), E(rho)
    var_u = np.where(pole, 0.0, np.maximum(E(u * u) - E_u**2, 0.0))
    var_rho = np.maximum(E(rho * rho) - E_rho**2, 0.0)
    cov = np.where(pole, 0.0, E(rho * u) - E_rho * E_u)
    return E_rho, E_u, var_rho, var_u, cov
