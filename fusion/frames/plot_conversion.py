"""Convert one radar's plot batch into system-frame positions and covariances.

The single entry point the tracker and the services call is :func:`convert_plots`.
It implements the three steps of [Dikić] (system-frame choice): (1) measurement → local ENU at the
radar, (2) ENU → system frame, (3) the measurement error (σ_D, σ_ψ, σ_θ or σ_h) →
covariance in the system frame, R = J_f J R_s Jᵀ J_fᵀ with the analytic polar Jacobian J
([Dikić] eq. 11-12) and the ENU → frame Jacobian J_f of
:meth:`SystemFrame.enu_jacobian`. Everything is vectorised over the plots of a batch.

Output coordinates follow the tracker convention of :mod:`fusion.frames.system_frame`:
x east, y north (, z up), metres.

Sensors beyond the rotating radar (``RadarSite.kind``):

* ``cartesian`` (multilateration relative to its reference point, the planar test
  sensor): (x east, y north) in the site's local tangent plane, the height the plot's
  ``altitude`` (else the assumed altitude, else the site's height) as u = h − h_site;
  C = diag(σ², σ², σ_h²) in the site's ENU with σ the plot's ``sigma`` (else the
  site's σ_c = ``sigma_cartesian``, grown with the distance ρ from the site as
  √(σ_c² + (g ρ)²), g = ``sigma_growth``: a multilateration system's geometry), then
  steps (2)-(3) as for a radar;
* ``wgs84`` (ADS-B): latitude/longitude and the same height rule, converted by the
  frame's geodesy (:meth:`SystemFrame.from_geodetic`), with C = diag(σ², σ², σ_h²) in the
  *plot's own* local ENU and R = J C Jᵀ, J = :meth:`SystemFrame.local_plane_jacobian`
  at the plot (no detour through a site's tangent plane: a report 90 km out would
  otherwise mix its height uncertainty into the horizontal through the 0.8° between the
  two verticals).

A reported velocity (``v_east``/``v_north``, σ ``sigma_velocity``) is carried into the
frame with the same Jacobian's horizontal block (``ConvertedPlots.velocity``).

Plots near the radar: a 2-D plot whose height and slant range disagree
(|sin e| ≥ 1) or whose elevation is ill-conditioned is kept, converted to the moments
of its position on the slant-range sphere (:func:`fusion.frames.polar.near_radar_moments`)
with a covariance covering the disagreement, and flagged in ``near_radar``; only
physically impossible values (range not > 0, no height and none assumed) are rejected.

Registration (docs/concepts/registration.md): a radar's estimated systematic errors
(:class:`fusion.frames.sensor_bias.SensorBias`) are removed from the reported range,
azimuth and time before step (1) (sensor_bias eq. 2), and the sensitivity of every
converted position to range and azimuth, ∂z/∂(D, ψ) = J_f J[:, :2], is returned for the
registration estimator (:mod:`fusion.registration`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from skyfuse.schemas import FrameKind, PlotBatch, RadarKind, RadarSite

from .geodesy import enu_to_geodetic, normal_section_radius
from .polar import (
    debiased_enu,
    elevation_from_altitude,
    near_radar_moments,
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
    bias: the correction that was applied (None: none).
    near_radar: (m,) bool, valid plots converted by the near-radar projection (height
      and slant range disagree, |sin e| ≥ 1, or the elevation is ill-conditioned close
      to the radar) — kept, with a covariance covering the disagreement.
    velocity: (m, 2) reported horizontal velocity in the frame, m/s (NaN where none;
      None: the batch has no velocity columns); velocity_var: (m,) its per-axis
      variance, m²/s² (NaN: unknown)."""

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
    near_radar: np.ndarray | None = None
    velocity: np.ndarray | None = None
    velocity_var: np.ndarray | None = None

    def __len__(self) -> int:
        return self.z.shape[0]

    @property
    def n_invalid(self) -> int:
        return int((~self.valid).sum())

    @property
    def n_near_radar(self) -> int:
        """Plots kept by the near-radar projection (a counter for the service Status)."""
        return 0 if self.near_radar is None else int(self.near_radar.sum())

    def take(self, idx: np.ndarray) -> ConvertedPlots:
        """The plots ``idx`` (every per-plot field alike; the batch-level ones kept)."""

        def rows(a):
            return None if a is None else a[idx]

        return dataclasses.replace(
            self,
            z=self.z[idx],
            R=self.R[idx],
            time=self.time[idx],
            valid=self.valid[idx],
            reasons=[self.reasons[i] for i in idx],
            notes=[self.notes[i] for i in idx] if self.notes else [],
            polar_jacobian=rows(self.polar_jacobian),
            slant_range=rows(self.slant_range),
            near_radar=rows(self.near_radar),
            velocity=rows(self.velocity),
            velocity_var=rows(self.velocity_var),
        )

    def select_valid(self) -> ConvertedPlots:
        """Only the valid plots (reasons/notes filtered alike)."""
        return self.take(np.flatnonzero(self.valid))


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
    debias: unbiased converted measurement ([LIT] Mo Longbin et al. 1998); polar radars only.
    assumed_altitude / sigma_assumed_altitude: height (m above the ellipsoid) used for
      2-D plots without a flight level (and 3-D plots without elevation or cartesian
      plots when ndim = 3); its standard deviation (m, default 3000) is carried through
      the elevation solve into the horizontal covariance.
    k_earth: effective-Earth factor for the 2-D elevation solve (1 = geometric WGS-84,
      solved exactly on the ellipsoid; 4/3 = standard refraction, sphere of k·R_α).
    bias: the radar's estimated systematic errors, removed from range, azimuth and the
      plot times first (sensor_bias eq. 2; polar radars only, None = no correction).

    Raises ValueError for a batch/site mismatch (wrong radar id, polar plots from a
    cartesian site or the reverse); bad individual plots are marked invalid with a reason.
    """
    sig_assumed = _check_arguments(
        site, batch, ndim, assumed_altitude, sigma_assumed_altitude, k_earth, bias
    )
    m = len(batch)
    time = batch.column("time") if m else np.zeros(0, np.int64)
    if bias is not None:
        time = time - bias.time_ns
    site_pos = frame.site_position(site.lat, site.lon, site.alt)
    if site.kind is RadarKind.WGS84:
        _check_geometry(site, batch, batch.is_geodetic, "lat/lon")
        z, R, valid, notes, Jh = _geodetic_plots(frame, site, batch, ndim, assumed_altitude,
                                                 sig_assumed)  # fmt: skip
        v, vv = _velocity(batch, Jh)
        return ConvertedPlots(
            z, R, time, valid, [""] * m, site_pos[:ndim].copy(), site.radar_id, ndim, notes,
            velocity=v, velocity_var=vv,
        )  # fmt: skip
    if site.kind is RadarKind.CARTESIAN:
        _check_geometry(site, batch, batch.is_cartesian, "x/y")
        enu, C, valid, reasons, notes = _cartesian_enu(
            site, batch, ndim, assumed_altitude, sig_assumed
        )
        height = np.full(m, np.nan)
        Jp = D = None
        near = np.zeros(m, bool)
    else:
        _check_geometry(site, batch, not (batch.is_cartesian or batch.is_geodetic),
                        "range/azimuth")  # fmt: skip
        P, height = _polar_enu(
            frame, site, batch, debias, assumed_altitude, sig_assumed, k_earth, bias
        )
        enu, C, valid, reasons, notes = P.enu, P.C, P.valid, P.reasons, P.notes
        Jp, D, near = P.Jp, P.D, P.near

    z, R, dz_dpolar, Jf = _to_frame(frame, site, enu, C, valid, height, Jp, site_pos, ndim)
    v, vv = _velocity(batch, Jf)
    return ConvertedPlots(
        z, R, time, valid, reasons, site_pos[:ndim].copy(), site.radar_id, ndim, notes,
        dz_dpolar, D, bias, near, v, vv,
    )  # fmt: skip


def _check_geometry(site, batch, fits: bool, columns: str) -> None:
    """ValueError when the batch's plots are not of the site's geometry."""
    if len(batch) and not fits:
        raise ValueError(
            f"radar {site.radar_id!r} is a {site.kind.value} sensor but its batch does not "
            f"carry {columns} plots"
        )


def _heights(site, batch, assumed_altitude, sig_assumed):
    """(h, σ_h, measured) (m,) of cartesian and WGS-84 plots: the plot's ``altitude``
    (σ = ``sigma_altitude``), else the assumed altitude (σ of the assumption), else the
    site's height (σ = ``sigma_cartesian``, the test sensor's convention)."""
    m = len(batch)
    alt = batch.column("altitude") if m else None
    measured = np.zeros(m, bool) if alt is None else np.isfinite(alt)
    h0 = site.alt if assumed_altitude is None else assumed_altitude
    s0 = site.sigma_cartesian if assumed_altitude is None else sig_assumed
    h = np.where(measured, alt, h0) if alt is not None else np.full(m, float(h0))
    sig = np.where(measured, site.sigma_altitude, s0)
    return h, sig, measured


def _plot_sigma(site, batch) -> np.ndarray:
    """Per-plot horizontal σ per axis (m,): the plot's ``sigma``, else the site's
    σ_c, for cartesian plots √(σ_c² + (g ρ)²) with g = ``sigma_growth`` and ρ the plot's
    distance from the site."""
    m = len(batch)
    base = np.full(m, site.sigma_cartesian)
    if m and site.sigma_growth > 0 and batch.is_cartesian:
        rho = np.hypot(batch.column("x"), batch.column("y"))
        base = np.sqrt(site.sigma_cartesian**2 + (site.sigma_growth * rho) ** 2)
    sig = batch.column("sigma") if m else None
    if sig is None:
        return base
    return np.where(np.isfinite(sig), sig, base)


def _geodetic_plots(frame, site, batch, ndim, assumed_altitude, sig_assumed):
    """WGS-84 plots (module docstring): positions through the frame's geodesy, R = J C Jᵀ
    with C in each plot's own ENU; returns z, R, valid, notes and J (m, 3, 3)."""
    m = len(batch)
    if m == 0:
        return (np.zeros((0, ndim)), np.zeros((0, ndim, ndim)), np.zeros(0, bool), [],
                np.zeros((0, 3, 3)))  # fmt: skip
    lat, lon = batch.column("lat"), batch.column("lon")
    h, sig_h, measured = _heights(site, batch, assumed_altitude, sig_assumed)
    x, y, zz = frame.from_geodetic(lat, lon, h)
    pos = np.stack([x, y, zz], axis=-1)
    J = frame.local_plane_jacobian(lat, lon, h)
    C = np.zeros((m, 3, 3))
    C[:, 0, 0] = C[:, 1, 1] = _plot_sigma(site, batch) ** 2
    C[:, 2, 2] = sig_h**2
    Rf = J @ C @ np.swapaxes(J, -1, -2)
    R = 0.5 * (Rf + np.swapaxes(Rf, -1, -2))[:, :ndim, :ndim]
    notes = ["" if ok else "assumed altitude" for ok in measured]
    return pos[:, :ndim].copy(), R, np.ones(m, bool), notes, J


def _velocity(batch, J) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The reported velocity (m, 2) in the frame (J's horizontal block applied to
    (v_east, v_north)) and its per-axis variance (m,), or (None, None) without one."""
    ve, vn = batch.column("v_east"), batch.column("v_north")
    if ve is None or vn is None or J is None:
        return None, None
    v = np.einsum("mij,mj->mi", J[:, :2, :2], np.stack([ve, vn], axis=-1))
    s = batch.column("sigma_velocity")
    var = np.full(len(v), np.nan) if s is None else s**2
    return v, var


def _to_frame(frame, site, enu, C, valid, height, Jp, site_pos, ndim):
    """Steps (2)-(3): site ENU → frame positions, R = J_f C J_fᵀ, ∂z/∂(D, ψ) = J_f Jp;
    also returns J_f (m, 3, 3) (identity where not valid or in the planar frame)."""
    m = len(valid)
    z = np.full((m, ndim), np.nan)
    R = np.full((m, ndim, ndim), np.nan)
    J_all = np.broadcast_to(np.eye(3), (m, 3, 3)).copy()
    dz_dpolar = None if Jp is None else np.full((m, ndim, 2), np.nan)
    idx = np.flatnonzero(valid)
    if idx.size and site.kind is RadarKind.CARTESIAN and frame.kind is FrameKind.PLANAR:
        # the plane is the frame: offsets from the site's plane position, R unchanged
        z[idx] = (enu[idx] + site_pos)[:, :ndim]
        R[idx] = C[idx][:, :ndim, :ndim]
    elif idx.size:
        pos, Jf = frame.enu_to_frame_with_jacobian(enu[idx], site.lat, site.lon, site.alt)
        J_all[idx] = Jf
        Rf = Jf @ C[idx] @ np.swapaxes(Jf, -1, -2)
        if frame.kind is not FrameKind.NED:
            # z is the height itself: keep a measured/assumed altitude exactly.
            known = np.isfinite(height[idx])
            pos[known, 2] = height[idx][known]
        z[idx] = pos[:, :ndim]
        R[idx] = 0.5 * (Rf + np.swapaxes(Rf, -1, -2))[:, :ndim, :ndim]
        if dz_dpolar is not None:
            dz_dpolar[idx] = (Jf @ Jp[idx][:, :, :2])[:, :ndim]
    return z, R, dz_dpolar, J_all


def _check_arguments(site, batch, ndim, assumed_altitude, sigma_assumed, k_earth, bias):
    """Batch-level argument checks of :func:`convert_plots` (ValueError naming the value);
    returns the σ of the assumed altitude (default 3000 m)."""
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
    sig_assumed = 3000.0 if sigma_assumed is None else float(sigma_assumed)
    if not sig_assumed > 0:
        raise ValueError(f"sigma_assumed_altitude = {sigma_assumed}: must be > 0 m")
    polar = site.kind in (RadarKind.TWO_D, RadarKind.THREE_D)
    if bias is not None and not polar and not bias.is_zero:
        raise ValueError(
            f"radar {site.radar_id!r} is a {site.kind.value} sensor: no bias correction"
        )
    return sig_assumed


def _cartesian_enu(site, batch, ndim, assumed_altitude, sig_assumed):
    """Cartesian sensor: (x east, y north) in the site plane, R = σ² I with σ the plot's
    ``sigma`` or the site's σ_c ([thesis] §7.3); the height by :func:`_heights`."""
    m = len(batch)
    enu = np.zeros((m, 3))
    if m:
        enu[:, 0] = batch.column("x")
        enu[:, 1] = batch.column("y")
    h, sig_h, _ = _heights(site, batch, assumed_altitude, sig_assumed)
    enu[:, 2] = h - site.alt
    C = np.zeros((m, 3, 3))
    C[:, 0, 0] = C[:, 1, 1] = _plot_sigma(site, batch) ** 2
    C[:, 2, 2] = sig_h**2
    valid = np.ones(m, bool)
    return enu, C, valid, [""] * m, [""] * m


@dataclass
class _Polar:
    """Working columns of one polar batch: bias-corrected range D and azimuth ψ,
    measured elevation, height h and its σ, which plots use a measured elevation, and
    the per-plot outputs filled by the conversion phases."""

    D: np.ndarray
    psi: np.ndarray
    elev: np.ndarray
    h: np.ndarray
    sig_h: np.ndarray
    use_elev: np.ndarray
    valid: np.ndarray
    reasons: list[str]
    notes: list[str]
    enu: np.ndarray
    C: np.ndarray
    Jp: np.ndarray  # ∂(e, n, u)/∂(D, ψ, θ or h)
    near: np.ndarray
    h_measured: np.ndarray


def _polar_enu(frame, site, batch, debias, assumed_altitude, sig_assumed, k_earth, bias):
    P = _polar_inputs(site, batch, bias, assumed_altitude, sig_assumed)
    i3 = np.flatnonzero(P.use_elev & P.valid)
    if i3.size:
        _enu_measured_elevation(P, site, i3, debias)
    i2 = np.flatnonzero(~P.use_elev & P.valid)
    if i2.size:
        _enu_from_height(P, site, i2, debias, k_earth)
    height = np.full(len(P.D), np.nan)
    height[i2] = P.h[i2]
    P.enu[~P.valid] = np.nan
    return P, height


def _polar_inputs(site, batch, bias, assumed_altitude, sig_assumed) -> _Polar:
    """Columns of the batch, the bias correction (sensor_bias eq. 2), the assumed
    altitude where a height is missing, and the checks of physically impossible values
    (range not > 0, no height and none assumed)."""
    m = len(batch)
    D = batch.column("range") if m else np.zeros(0)
    psi = batch.column("azimuth") if m else np.zeros(0)
    if bias is not None and m:
        D, psi, _ = bias.correct(D, psi, np.zeros(0, np.int64))
    elev = batch.column("elevation")
    alt = batch.column("altitude")
    elev = np.full(m, np.nan) if elev is None else elev
    h = np.full(m, np.nan) if alt is None else alt.copy()
    P = _Polar(
        D, psi, elev, h, np.full(m, site.sigma_altitude),
        np.isfinite(elev) if site.kind is RadarKind.THREE_D else np.zeros(m, bool),
        np.ones(m, bool), [""] * m, [""] * m,
        np.zeros((m, 3)), np.zeros((m, 3, 3)), np.full((m, 3, 3), np.nan), np.zeros(m, bool),
        np.isfinite(h),
    )  # fmt: skip
    need_h = ~P.use_elev & ~np.isfinite(h)
    if need_h.any():
        if assumed_altitude is None:
            what = "altitude (flight level)" if site.kind is RadarKind.TWO_D else "elevation"
            for i in np.flatnonzero(need_h):
                P.reasons[i] = f"plot {i}: {what} unknown and no assumed_altitude configured"
            P.valid &= ~need_h
        else:
            h[need_h] = assumed_altitude
            P.sig_h[need_h] = sig_assumed
            for i in np.flatnonzero(need_h):
                P.notes[i] = f"assumed altitude {assumed_altitude} m ± {sig_assumed} m"
    bad_range = ~(D > 0)
    for i in np.flatnonzero(bad_range & P.valid):
        P.reasons[i] = f"plot {i}: range = {D[i]} m: must be > 0"
    P.valid &= ~bad_range
    return P


def _enu_measured_elevation(P: _Polar, site, i3, debias) -> None:
    """3-D radar plots with a measured elevation ([Dikić] eq. 7, 11-12)."""
    D, psi, th, sD = P.D[i3], P.psi[i3], P.elev[i3], site.sigma_range
    J = spherical_jacobian(D, psi, th)
    P.Jp[i3] = J
    if debias:
        mom = vertical_moments_3d(D, sD, th, site.sigma_elevation)
        lam_t = np.exp(-0.5 * site.sigma_elevation**2)
        P.enu[i3], P.C[i3] = debiased_enu(
            D * np.cos(th), D * np.sin(th), None, psi, site.sigma_azimuth,
            lam_vertical=lam_t, moments_vertical=mom,
        )  # fmt: skip
    else:
        P.enu[i3] = spherical_to_enu(D, psi, th)
        Rs = np.diag([sD**2, site.sigma_azimuth**2, site.sigma_elevation**2])
        P.C[i3] = J @ Rs @ np.swapaxes(J, -1, -2)


def _enu_from_height(P: _Polar, site, i2, debias, k_earth) -> None:
    """Plots whose elevation comes from a height (2-D radars): θ(D, h) on the
    sphere, refined on the ellipsoid; where the height and the slant range disagree or
    θ is ill-conditioned (close to or over the radar) the near-radar projection of
    :func:`fusion.frames.polar.near_radar_moments` instead."""
    radius = k_earth * normal_section_radius(site.lat, P.psi[i2])
    sol = elevation_from_altitude(P.D[i2], P.h[i2], site.alt, radius)
    D = P.D[i2]
    u_m = D * sol.sin_theta  # height above the site's tangent plane the altitude implies
    du_dh = (radius + P.h[i2]) / (radius + site.alt)  # ∂(D sinθ)/∂h on the sphere
    sig_u = _near_radar_sigma(D, u_m, du_dh * P.sig_h[i2], site.sigma_range)
    # an assumed altitude keeps the linearised conversion unless impossible
    measured = P.h_measured[i2]
    near = (measured & _ill_conditioned(D, u_m, sig_u, site.sigma_range)) | ~sol.feasible
    if near.any():
        _enu_near_radar(P, site, i2[near], u_m[near], sig_u[near], sol.sin_theta[near])
    keep = ~near
    i2, theta = i2[keep], sol.theta[keep]
    if i2.size == 0:
        return
    D, psi, h = P.D[i2], P.psi[i2], P.h[i2]
    dth_dD, dth_dh = sol.dtheta_dD[keep], sol.dtheta_dh[keep]
    if k_earth == 1.0:
        theta = _refine_elevation_on_ellipsoid(site, D, psi, h, theta)
    # Jacobian of (D, ψ, h) → (e, n, u) through θ(D, h).
    T = np.zeros((i2.size, 3, 3))
    T[:, 0, 0] = T[:, 1, 1] = 1.0
    T[:, 2, 0] = dth_dD
    T[:, 2, 2] = dth_dh
    J = spherical_jacobian(D, psi, theta) @ T
    P.Jp[i2] = J
    sD, sPsi, sh = site.sigma_range, site.sigma_azimuth, P.sig_h[i2]
    if debias:
        # (ρ, u) are nearly linear in (D, h): their covariance by linearisation.
        st, ct = np.sin(theta), np.cos(theta)
        A = np.zeros((i2.size, 2, 2))
        A[:, 0, 0] = ct - D * st * dth_dD
        A[:, 0, 1] = -D * st * dth_dh
        A[:, 1, 0] = st + D * ct * dth_dD
        A[:, 1, 1] = D * ct * dth_dh
        Cru = A @ (np.eye(2) * np.stack([np.full(i2.size, sD**2), sh**2], -1)[:, None])
        Cru = Cru @ np.swapaxes(A, -1, -2)
        P.enu[i2], P.C[i2] = debiased_enu(D * ct, D * st, Cru, psi, sPsi)
    else:
        Rs = np.zeros((i2.size, 3, 3))
        Rs[:, 0, 0], Rs[:, 1, 1], Rs[:, 2, 2] = sD**2, sPsi**2, sh**2
        P.enu[i2] = spherical_to_enu(D, psi, theta)
        P.C[i2] = J @ Rs @ np.swapaxes(J, -1, -2)


_CROSS_RANGE_FLOOR = 1.0  # m², see _enu_near_radar
NEAR_RADAR_NONLINEARITY = 0.1
"""Linearisation limit: a plot is converted by the near-radar projection when the
second-order term of ρ(u) = √(D² − u²) over σ_u, ½|ρ''|σ_u² = ½ D² σ_u²/ρ³, exceeds this
fraction of the linearised ground-range σ, √(u² σ_u² + D² σ_D²)/ρ — i.e. when
½ D² σ_u² / (ρ² √(u² σ_u² + D² σ_D²)) > 0.1 — or when |sin θ| ≥ 1 (no real ρ)."""


def _near_radar_sigma(D, u_m, sig_u_h, sigma_range):
    """σ of the height above the site plane for the near-radar projection: the height
    noise, the range noise (the sphere's radius is itself measured) and the observed
    disagreement max(|u_m| − D, 0) (barometric vs geometric height, a wrong code), so
    that the covariance covers it: σ_u² = σ_h² + σ_D² + max(|u_m| − D, 0)²."""
    excess = np.maximum(np.abs(u_m) - D, 0.0)
    return np.sqrt(sig_u_h**2 + sigma_range**2 + excess**2)


def _ill_conditioned(D, u_m, sig_u, sigma_range):
    """The criterion of :data:`NEAR_RADAR_NONLINEARITY` (vectorised)."""
    rho2 = D * D - u_m * u_m
    lin = np.sqrt((u_m * sig_u) ** 2 + (D * sigma_range) ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = 0.5 * D * D * sig_u**2 / (rho2 * lin)
    return ~(rho2 > 0) | ~(ratio <= NEAR_RADAR_NONLINEARITY)


def _enu_near_radar(P: _Polar, site, idx, u_m, sig_u, sin_theta) -> None:
    """Near-radar projection: the truncated-Gaussian moments of (ρ, u) on
    the slant-range sphere (:func:`near_radar_moments`), then e = ρ sinψ, n = ρ cosψ with

        C = Var ρ r̂r̂ᵀ + (E[ρ²] σ_ψ² + 1 m²) t̂t̂ᵀ (+ Var u and Cov(ρ, u) r̂ vertically),

    r̂ = (sinψ, cosψ, 0), t̂ = (cosψ, −sinψ, 0). The 1 m² cross-range floor keeps the
    covariance from collapsing to a line over the radar (ρ → 0) and covers the
    spherical approximation (centimetres). No Jacobian is given (the registration does
    not use these plots)."""
    E_rho, E_u, var_rho, var_u, cov_ru = near_radar_moments(P.D[idx], u_m, sig_u)
    sp, cp = np.sin(P.psi[idx]), np.cos(P.psi[idx])
    r_hat = np.stack([sp, cp, np.zeros_like(sp)], -1)
    t_hat = np.stack([cp, -sp, np.zeros_like(sp)], -1)
    outer = lambda a, b: a[:, :, None] * b[:, None, :]  # noqa: E731
    C = var_rho[:, None, None] * outer(r_hat, r_hat)
    cross = (var_rho + E_rho**2) * site.sigma_azimuth**2 + _CROSS_RANGE_FLOOR
    C += cross[:, None, None] * outer(t_hat, t_hat)
    up = np.zeros_like(r_hat)
    up[:, 2] = 1.0
    C += cov_ru[:, None, None] * (outer(r_hat, up) + outer(up, r_hat))
    C += var_u[:, None, None] * outer(up, up)
    P.enu[idx] = E_rho[:, None] * r_hat + E_u[:, None] * up
    P.C[idx] = C
    P.near[idx] = True
    for j, i in enumerate(idx):
        gap = abs(u_m[j]) - P.D[i]
        what = "disagree" if abs(sin_theta[j]) >= 1.0 else "ill-conditioned"
        P.notes[i] = (P.notes[i] + "; " if P.notes[i] else "") + (
            f"near the radar ({what}: height vs slant range {gap:+.0f} m): projected on the "
            f"range sphere, ± {np.sqrt(var_rho[j]):.0f} m in ground range"
        )


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
