"""Convert one radar's plot batch into system-frame positions and covariances.

The single entry point the tracker and the services call is :func:`convert_plots`.
It implements the three steps of spec 01 §1 (004): (1) measurement → local ENU at the
radar, (2) ENU → system frame, (3) the measurement error (σ_D, σ_ψ, σ_θ or σ_h) →
covariance in the system frame, R = J_f J R_s Jᵀ J_fᵀ with the analytic polar Jacobian J
(spec 01 §2, 004 eq. 11-12) and the ENU → frame Jacobian J_f of
:meth:`SystemFrame.enu_jacobian`. Everything is vectorised over the plots of a batch.

Output coordinates follow the tracker convention of :mod:`fusion.frames.system_frame`:
x east, y north (, z up), metres.

Registration (issue 17): a radar's estimated systematic errors
(:class:`fusion.frames.sensor_bias.SensorBias`) are removed from the reported range,
azimuth and time before step (1) (sensor_bias eq. 2), and the sensitivity of every
converted position to range and azimuth, ∂z/∂(D, ψ) = J_f J[:, :2], is returned for the
registration estimator (:mod:`fusion.registration`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from skyfuse.schemas import FrameKind, PlotBatch, RadarKind, RadarSite

from .geodesy import enu_to_geodetic, normal_section_radius
from .polar import (
    debiased_enu,
    elevation_from_altitude,
    spherical_jacobian,
    spherical_to_enu,
    vertical_moments_3d,
)
from .sensor_bias import SensorBias
from .system_frame import SystemFrame

_ELEVATION_NEWTON_STEPS = 3


@dataclass
class ConvertedPlots:
    """Plots of one batch in the system frame (row i ↔ plot i of the batch).

    z: (m, ndim) positions, metres (x east, y north[, z up]); NaN where not valid.
    R: (m, ndim, ndim) measurement covariances, m²; NaN where not valid.
    time: (m,) int64 plot times, ns UTC.
    valid: (m,) bool; ``reasons[i]`` says why plot i is invalid ('' when valid).
    site_position: (ndim,) the radar's position in the frame.
    notes: per-plot remarks on valid plots (e.g. an assumed altitude was used).
    polar_jacobian: (m, ndim, 2) ∂z/∂(D, ψ) in m/m and m/rad (polar radars; NaN where
      not valid), the sensitivity of a position to range and azimuth errors.
    slant_range: (m,) bias-corrected slant range D, m (polar radars).
    bias: the correction that was applied (None: none)."""

    z: np.ndarray
    R: np.ndarray
    time: np.ndarray
    valid: np.ndarray
    reasons: list[str]
    site_position: np.ndarray
    radar_id: str
    ndim: int
    notes: list[str] = field(default_factory=list)
    polar_jacobian: np.ndarray | None = None
    slant_range: np.ndarray | None = None
    bias: SensorBias | None = None

    def __len__(self) -> int:
        return self.z.shape[0]

    @property
    def n_invalid(self) -> int:
        return int((~self.valid).sum())

    def select_valid(self) -> ConvertedPlots:
        """Only the valid plots (reasons/notes filtered alike)."""
        idx = np.flatnonzero(self.valid)
        return ConvertedPlots(
            self.z[idx],
            self.R[idx],
            self.time[idx],
            self.valid[idx],
            [self.reasons[i] for i in idx],
            self.site_position,
            self.radar_id,
            self.ndim,
            [self.notes[i] for i in idx] if self.notes else [],
            None if self.polar_jacobian is None else self.polar_jacobian[idx],
            None if self.slant_range is None else self.slant_range[idx],
            self.bias,
        )


def convert_plots(
    frame: SystemFrame,
    site: RadarSite,
    batch: PlotBatch,
    *,
    debias: bool = False,
    ndim: int = 2,
    assumed_altitude: float | None = None,
    sigma_assumed_altitude: float | None = None,
    k_earth: float = 1.0,
    bias: SensorBias | None = None,
) -> ConvertedPlots:
    """Convert ``batch`` (plots of radar ``site``) into ``frame``.

    ndim: 2 → horizontal (x, y) only; 3 → (x, y, z) with z up.
    debias: unbiased converted measurement (spec 01 §2 [LIT]); polar radars only.
    assumed_altitude / sigma_assumed_altitude: height (m above the ellipsoid) used for
      2-D plots without a flight level (and 3-D plots without elevation or cartesian
      plots when ndim = 3); its standard deviation (m, default 3000) is carried through
      the elevation solve into the horizontal covariance (issue 7).
    k_earth: effective-Earth factor for the 2-D elevation solve (1 = geometric WGS-84,
      solved exactly on the ellipsoid; 4/3 = standard refraction, sphere of k·R_α).
    bias: the radar's estimated systematic errors, removed from range, azimuth and the
      plot times first (sensor_bias eq. 2; polar radars only, None = no correction).

    Raises ValueError for a batch/site mismatch (wrong radar id, polar plots from a
    cartesian site or the reverse); bad individual plots are marked invalid with a reason.
    """
    if ndim not in (2, 3):
        raise ValueError(f"ndim = {ndim}: must be 2 or 3")
    if batch.radar_id != site.radar_id:
        raise ValueError(
            f"batch.radar_id = {batch.radar_id!r} does not match site.radar_id = {site.radar_id!r}"
        )
    if not k_earth > 0:
        raise ValueError(f"k_earth = {k_earth}: must be > 0")
    if assumed_altitude is not None and not np.isfinite(assumed_altitude):
        raise ValueError(f"assumed_altitude = {assumed_altitude}: must be finite metres")
    sig_assumed = 3000.0 if sigma_assumed_altitude is None else float(sigma_assumed_altitude)
    if not sig_assumed > 0:
        raise ValueError(f"sigma_assumed_altitude = {sigma_assumed_altitude}: must be > 0 m")

    m = len(batch)
    time = batch.column("time") if m else np.zeros(0, np.int64)
    if bias is not None and site.kind is RadarKind.CARTESIAN and not bias.is_zero:
        raise ValueError(f"radar {site.radar_id!r} is a cartesian sensor: no bias correction")
    if bias is not None:
        time = time - bias.time_ns
    site_pos = frame.site_position(site.lat, site.lon, site.alt)
    if site.kind is RadarKind.CARTESIAN:
        if m and not batch.is_cartesian:
            raise ValueError(
                f"radar {site.radar_id!r} is a cartesian sensor but its batch carries "
                "range/azimuth plots"
            )
        enu, C, valid, reasons, notes = _cartesian_enu(
            site, batch, ndim, assumed_altitude, sig_assumed
        )
        height = np.full(m, np.nan)
        Jp = D = None
    else:
        if m and batch.is_cartesian:
            raise ValueError(
                f"radar {site.radar_id!r} is a {site.kind.value} radar but its batch carries "
                "x/y plots"
            )
        enu, C, valid, reasons, notes, height, Jp, D = _polar_enu(
            frame, site, batch, debias, assumed_altitude, sig_assumed, k_earth, bias
        )

    z = np.full((m, ndim), np.nan)
    R = np.full((m, ndim, ndim), np.nan)
    dz_dpolar = None if Jp is None else np.full((m, ndim, 2), np.nan)
    idx = np.flatnonzero(valid)
    if idx.size and site.kind is RadarKind.CARTESIAN and frame.kind is FrameKind.PLANAR:
        # the plane is the frame: offsets from the site's plane position, R unchanged
        z[idx] = (enu[idx] + site_pos)[:, :ndim]
        R[idx] = C[idx][:, :ndim, :ndim]
    elif idx.size:
        pos, Jf = frame.enu_to_frame_with_jacobian(enu[idx], site.lat, site.lon, site.alt)
        Rf = Jf @ C[idx] @ np.swapaxes(Jf, -1, -2)
        if frame.kind is not FrameKind.NED:
            # z is the height itself: keep a measured/assumed altitude exactly.
            known = np.isfinite(height[idx])
            pos[known, 2] = height[idx][known]
        z[idx] = pos[:, :ndim]
        R[idx] = 0.5 * (Rf + np.swapaxes(Rf, -1, -2))[:, :ndim, :ndim]
        if dz_dpolar is not None:
            dz_dpolar[idx] = (Jf @ Jp[idx][:, :, :2])[:, :ndim]
    return ConvertedPlots(
        z, R, time, valid, reasons, site_pos[:ndim].copy(), site.radar_id, ndim, notes,
        dz_dpolar, D, bias,
    )  # fmt: skip


def _cartesian_enu(site, batch, ndim, assumed_altitude, sig_assumed):
    """Cartesian test sensor: (x east, y north) in the site plane, R = σ_c² I (spec 02 §1).
    The height is the assumed altitude (or the site height) when ndim = 3."""
    m = len(batch)
    enu = np.zeros((m, 3))
    if m:
        enu[:, 0] = batch.column("x")
        enu[:, 1] = batch.column("y")
    h = site.alt if assumed_altitude is None else assumed_altitude
    sig_h = site.sigma_cartesian if assumed_altitude is None else sig_assumed
    enu[:, 2] = h - site.alt
    C = np.zeros((m, 3, 3))
    C[:, 0, 0] = C[:, 1, 1] = site.sigma_cartesian**2
    C[:, 2, 2] = sig_h**2
    valid = np.ones(m, bool)
    return enu, C, valid, [""] * m, [""] * m


def _polar_enu(frame, site, batch, debias, assumed_altitude, sig_assumed, k_earth, bias):
    m = len(batch)
    D = batch.column("range") if m else np.zeros(0)
    psi = batch.column("azimuth") if m else np.zeros(0)
    if bias is not None and m:
        D, psi, _ = bias.correct(D, psi, np.zeros(0, np.int64))
    elev = batch.column("elevation")
    alt = batch.column("altitude")
    elev = np.full(m, np.nan) if elev is None else elev
    alt = np.full(m, np.nan) if alt is None else alt
    reasons = [""] * m
    notes = [""] * m
    valid = np.ones(m, bool)
    sD, sPsi = site.sigma_range, site.sigma_azimuth

    # Which plots use a measured elevation (3-D radar) and which solve it from a height.
    use_elev = np.isfinite(elev) if site.kind is RadarKind.THREE_D else np.zeros(m, bool)
    h = alt.copy()
    sig_h = np.full(m, site.sigma_altitude)
    need_h = ~use_elev & ~np.isfinite(h)
    if need_h.any():
        if assumed_altitude is None:
            what = "altitude (flight level)" if site.kind is RadarKind.TWO_D else "elevation"
            for i in np.flatnonzero(need_h):
                reasons[i] = f"plot {i}: {what} unknown and no assumed_altitude configured"
            valid &= ~need_h
        else:
            h[need_h] = assumed_altitude
            sig_h[need_h] = sig_assumed
            for i in np.flatnonzero(need_h):
                notes[i] = f"assumed altitude {assumed_altitude} m ± {sig_assumed} m"
    bad_range = ~(D > 0)
    for i in np.flatnonzero(bad_range & valid):
        reasons[i] = f"plot {i}: range = {D[i]} m: must be > 0"
    valid &= ~bad_range

    enu = np.zeros((m, 3))
    C = np.zeros((m, 3, 3))
    Jp = np.full((m, 3, 3), np.nan)  # ∂(e, n, u)/∂(D, ψ, θ or h)
    # --- 3-D radar plots with a measured elevation ------------------------------------
    i3 = np.flatnonzero(use_elev & valid)
    if i3.size:
        th = elev[i3]
        Jp[i3] = spherical_jacobian(D[i3], psi[i3], th)
        if debias:
            mom = vertical_moments_3d(D[i3], sD, th, site.sigma_elevation)
            rho_m, u_m = D[i3] * np.cos(th), D[i3] * np.sin(th)
            lam_t = np.exp(-0.5 * site.sigma_elevation**2)
            enu[i3], C[i3] = debiased_enu(
                rho_m, u_m, None, psi[i3], sPsi, lam_vertical=lam_t, moments_vertical=mom
            )
        else:
            enu[i3] = spherical_to_enu(D[i3], psi[i3], th)
            J = spherical_jacobian(D[i3], psi[i3], th)
            Rs = np.diag([sD**2, sPsi**2, site.sigma_elevation**2])
            C[i3] = J @ Rs @ np.swapaxes(J, -1, -2)
    # --- plots whose elevation comes from a height -------------------------------------
    i2 = np.flatnonzero(~use_elev & valid)
    if i2.size:
        radius = k_earth * normal_section_radius(site.lat, psi[i2])
        sol = elevation_from_altitude(D[i2], h[i2], site.alt, radius)
        bad = ~sol.feasible
        for j in np.flatnonzero(bad):
            i = i2[j]
            reasons[i] = (
                f"plot {i}: range = {D[i]:.1f} m and altitude = {h[i]:.1f} m are "
                f"inconsistent with the site height {site.alt} m (|sin elevation| >= 1)"
            )
        valid[i2[bad]] = False
        keep = ~bad
        i2, theta = i2[keep], sol.theta[keep]
        dth_dD, dth_dh = sol.dtheta_dD[keep], sol.dtheta_dh[keep]
        if i2.size and k_earth == 1.0:
            theta = _refine_elevation_on_ellipsoid(site, D[i2], psi[i2], h[i2], theta)
        # Jacobian of (D, ψ, h) → (e, n, u) through θ(D, h).
        Js = spherical_jacobian(D[i2], psi[i2], theta)
        T = np.zeros((i2.size, 3, 3))
        T[:, 0, 0] = T[:, 1, 1] = 1.0
        T[:, 2, 0] = dth_dD
        T[:, 2, 2] = dth_dh
        J = Js @ T
        Jp[i2] = J
        Rs = np.zeros((i2.size, 3, 3))
        Rs[:, 0, 0], Rs[:, 1, 1], Rs[:, 2, 2] = sD**2, sPsi**2, sig_h[i2] ** 2
        if debias:
            rho = D[i2] * np.cos(theta)
            u = D[i2] * np.sin(theta)
            # (ρ, u) are nearly linear in (D, h): their covariance by linearisation.
            A = np.zeros((i2.size, 2, 2))
            A[:, 0, 0] = np.cos(theta) - D[i2] * np.sin(theta) * dth_dD
            A[:, 0, 1] = -D[i2] * np.sin(theta) * dth_dh
            A[:, 1, 0] = np.sin(theta) + D[i2] * np.cos(theta) * dth_dD
            A[:, 1, 1] = D[i2] * np.cos(theta) * dth_dh
            Cdh = np.zeros((i2.size, 2, 2))
            Cdh[:, 0, 0], Cdh[:, 1, 1] = sD**2, sig_h[i2] ** 2
            Cru = A @ Cdh @ np.swapaxes(A, -1, -2)
            enu[i2], C[i2] = debiased_enu(rho, u, Cru, psi[i2], sPsi)
        else:
            enu[i2] = spherical_to_enu(D[i2], psi[i2], theta)
            C[i2] = J @ Rs @ np.swapaxes(J, -1, -2)
    height = np.full(m, np.nan)
    height[i2] = h[i2]
    enu[~valid] = np.nan
    return enu, C, valid, reasons, notes, height, Jp, D


def _refine_elevation_on_ellipsoid(site, D, psi, h, theta0):
    """Newton iterations on θ so that the point at (D, ψ, θ) from the site has height h
    above the WGS-84 ellipsoid exactly (the sphere formula is the first guess)."""
    theta = theta0.copy()
    step = 1e-7
    for _ in range(_ELEVATION_NEWTON_STEPS):
        both = np.concatenate([theta, theta + step])
        enu = spherical_to_enu(np.tile(D, 2), np.tile(psi, 2), both)
        _, _, alt = enu_to_geodetic(enu, site.lat, site.lon, site.alt)
        f0, f1 = alt[: D.size] - h, alt[D.size :] - h
        if np.abs(f0).max() < 1e-4:  # 0.1 mm in height: converged
            break
        slope = (f1 - f0) / step
        ok = np.abs(slope) > 1e-6
        theta = np.where(ok, theta - np.where(ok, f0 / np.where(ok, slope, 1.0), 0.0), theta)
    return theta
