"""Tracker input: :class:`MeasurementBatch` (one radar sector or scan in the system frame)
and :class:`SectorCoverage` (which predicted positions that radar could have detected).

Positions are in the system frame (metres); covariances in m²; times in integer ns UTC.

The cone of silence: a rotating surveillance radar's antenna does not illuminate targets
above its maximum elevation e_max, so an aircraft flying over the radar is not detected
for tens of seconds (the cone of silence). The elevation of a target at height h above the
ellipsoid and ground distance ρ from a site at height h_r, on a sphere of the effective
Earth radius a = k R (the 4/3-Earth model of standard refraction, k = 4/3; the plot
conversion's ``k_earth``), follows from the positions relative to the sphere's centre,
target (a + h)(sin(ρ/a), cos(ρ/a)) and site (0, a + h_r):

    e = atan2((a + h) cos(ρ/a) − (a + h_r), (a + h) sin(ρ/a))              (C1)

A position is *in the cone* when e > e_max (:meth:`SectorCoverage.in_cone`).

Detection share (:meth:`SectorCoverage.detection_share`): for a track whose position is
Gaussian with per-axis σ about the predicted position (ground range ρ, azimuth α,
elevation e), the probability that the radar could have seen it in this batch, linearised
in each limit (Φ the standard normal CDF, σ_α = σ/ρ, σ_e = σ |∂e/∂ρ| with
∂e/∂ρ ≈ −Δh/(ρ² + Δh²), Δh = h − h_r, plus σ_e0 = 0.5° for the height and the antenna
pattern):

    P_sector = Φ((w − a)/σ_α) − Φ(−a/σ_α),   a = (α − α_start) mod 2π, w the width  (C2)
    P_range  = Φ((ρ_max − ρ)/σ) − Φ((ρ_min − ρ)/σ)                               (C3)
    P_cone   = Φ((e_max − e)/σ_e)            (1 where h is unknown or no cone)    (C4)

Sensors beyond the rotating radar (docs/concepts/sensors.md) add to the same coverage: a
polygon (the site's ``coverage`` in the frame: :mod:`.coverage_polygon`, share Φ(d/σ)
of the signed distance d to its boundary), a ceiling h_max (a surface movement radar:
share Φ((h_max − h)/σ_h), σ_h = :data:`CEILING_SIGMA`, 1 where h is unknown), their
``timing`` (``sweep``: the beam crosses the sector from time_start to time_end;
``plots``: each track's time is that of the batch's plot nearest to it, for sensors
without a sweep or whose sweep's azimuth is not known) and their ``detection`` semantics
(``sweep`` or ``reports``: :mod:`.report_clock`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.special import ndtr
from skyfuse.fusion.filters.cholesky_kernels import positive_definite

from .coverage_polygon import share_inside, signed_distance
from .identity import PlotIdentity
from .plot_validity_kernel import all_plots_valid

TWO_PI = 2.0 * np.pi
#: Effective Earth radius k R with k = 4/3 (standard refraction), R = 6,371,008.8 m (mean).
EFFECTIVE_EARTH_RADIUS = 4.0 / 3.0 * 6_371_008.8
#: [IMPL] default upper elevation limit of a surveillance radar's antenna, rad (45°: the
#: usual upper limit of an MSSR antenna's vertical coverage; the Barcelona radar's highest
#: plots are at 44-46°). A RadarSite field ``max_elevation`` takes precedence.
DEFAULT_MAX_ELEVATION = np.radians(45.0)
#: σ_e0 of (C4): elevation spread of the cone's edge (height error, antenna pattern), rad.
CONE_EDGE_SIGMA = np.radians(0.5)
#: σ_h of the ceiling share: the height of a track's last plot (a flight level, 25 ft
#: steps, and the pressure-to-geometric difference near the ground), m.
CEILING_SIGMA = 30.0


def elevation_angle(
    ground_range: np.ndarray,
    height: np.ndarray,
    site_height: float,
    earth_radius: float = EFFECTIVE_EARTH_RADIUS,
) -> np.ndarray:
    """Elevation (rad) of targets at ``height`` (m) and ``ground_range`` (m) seen from a
    site at ``site_height`` (m), eq. (C1) of the module docstring."""
    a = float(earth_radius)
    rho = np.asarray(ground_range, dtype=np.float64)
    h = np.asarray(height, dtype=np.float64)
    ang = rho / a
    return np.arctan2((a + h) * np.cos(ang) - (a + site_height), (a + h) * np.sin(ang))


@dataclass
class SectorCoverage:
    """A rotating radar's view during one batch: site position, range interval and the
    azimuth sector swept clockwise from ``sector_start`` over ``sector_width`` (rad, from
    north of the system frame) between ``time_start`` and ``time_end`` (ns).

    ``axes`` are the indices of the (east, north) coordinates in a position vector: (0, 1)
    for the stereographic/planar frames (x east, y north), (1, 0) for NED (x north).

    ``max_elevation`` (rad; None: no cone of silence) and ``site_height`` (m above the
    ellipsoid) define the cone of silence (C1); ``earth_radius`` is the effective radius
    a of (C1), m. ``polygon`` (V, 2) frame vertices (east, north; None: the range ring
    alone), ``max_height`` m (None: no ceiling), ``timing`` and ``detection`` (module
    docstring), ``report_timeout`` s (``detection = "reports"``)."""

    site: np.ndarray
    min_range: float = 0.0
    max_range: float = np.inf
    sector_start: float = 0.0
    sector_width: float = TWO_PI
    time_start: int = 0
    time_end: int = 0
    axes: tuple[int, int] = (0, 1)
    max_elevation: float | None = None
    site_height: float = 0.0
    earth_radius: float = EFFECTIVE_EARTH_RADIUS
    polygon: np.ndarray | None = None
    max_height: float | None = None
    timing: str = "sweep"
    detection: str = "sweep"
    report_timeout: float = 10.0

    def in_cone(self, pos: np.ndarray, height: np.ndarray) -> np.ndarray:
        """True where a target at horizontal position ``pos`` (n, ≥2) and ``height`` (n,)
        m is above the radar's maximum elevation (C1); False where the height is unknown
        (NaN) or there is no cone. The frame's horizontal distance stands for the ground
        distance ρ (stereographic scale error below 1e-5 within 50 km of the origin)."""
        pos = np.atleast_2d(pos)
        h = np.asarray(height, dtype=np.float64).reshape(-1)
        if self.max_elevation is None or len(h) == 0:
            return np.zeros(len(h), bool)
        r, _ = self._polar(pos)
        known = np.isfinite(h)
        e = elevation_angle(r, np.where(known, h, 0.0), self.site_height, self.earth_radius)
        return known & (e > self.max_elevation)

    def detection_share(
        self, pos: np.ndarray, sigma: np.ndarray, height: np.ndarray, polar=None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(P_sector · P_range, P_cone) of (C2)-(C4) for positions ``pos`` (n, ≥2) with
        per-axis σ ``sigma`` (n,) m and heights ``height`` (n,) m (NaN unknown);
        ``polar``: their (range, azimuth) when already computed (:meth:`polar`)."""
        pos = np.atleast_2d(pos)
        polar = self._polar(pos) if polar is None else polar
        r = polar[0]
        s = np.maximum(np.asarray(sigma, dtype=np.float64), 1e-3)
        share = ndtr((self.max_range - r) / s) - ndtr((self.min_range - r) / s)
        if self.sector_width < TWO_PI:
            a = self.sector_fraction(pos, polar) * self.sector_width
            s_a = s / np.maximum(r, 1.0)
            share = share * (ndtr((self.sector_width - a) / s_a) - ndtr(-a / s_a))
        h = np.asarray(height, dtype=np.float64).reshape(-1)
        cone = np.ones(len(r))
        known = np.isfinite(h)
        if self.max_elevation is not None and known.any():
            hk, rk, sk = h[known], r[known], s[known]
            e = elevation_angle(rk, hk, self.site_height, self.earth_radius)
            dh = hk - self.site_height
            s_e = np.hypot(sk * np.abs(dh) / (rk**2 + dh**2 + 1.0), CONE_EDGE_SIGMA)
            cone[known] = ndtr((self.max_elevation - e) / s_e)
        if self.polygon is not None:
            share = share * share_inside(self._plane(pos), s, self.polygon)
        if self.max_height is not None and known.any():
            share[known] *= ndtr((self.max_height - h[known]) / CEILING_SIGMA)
        return share, cone

    def _plane(self, pos: np.ndarray) -> np.ndarray:
        """(east, north) of positions, the polygon's axes."""
        return np.column_stack([pos[:, self.axes[0]], pos[:, self.axes[1]]])

    def _polar(self, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        e = pos[:, self.axes[0]] - self.site[self.axes[0]]
        n = pos[:, self.axes[1]] - self.site[self.axes[1]]
        return np.hypot(e, n), np.mod(np.arctan2(e, n), TWO_PI)

    def sector_fraction(self, pos: np.ndarray, polar=None) -> np.ndarray:
        """Where in the sweep each position lies: 0 at sector_start, 1 at its end; values
        outside [0, 1] are outside the sector (negative: before its start). ``polar``:
        the positions' (range, azimuth) when already computed (:meth:`polar`)."""
        _, az = self._polar(pos) if polar is None else polar
        off = np.mod(az - self.sector_start, TWO_PI)
        # put offsets in the half-turn before the sector at negative values
        off = np.where(off > 0.5 * (TWO_PI + self.sector_width), off - TWO_PI, off)
        return off / self.sector_width

    def polar(self, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(horizontal range m, azimuth rad from north) of positions ``pos`` (n, ≥2) from
        the site, to pass to several of the tests below (computed once)."""
        return self._polar(np.atleast_2d(pos))

    def contains(self, pos: np.ndarray, margin: np.ndarray | float = 0.0, polar=None) -> np.ndarray:
        """True where a position (within ``margin`` metres) is inside range and sector."""
        pos = np.atleast_2d(pos)
        polar = self._polar(pos) if polar is None else polar
        r = polar[0]
        margin = np.broadcast_to(np.asarray(margin, dtype=np.float64), r.shape)
        ok = (r >= self.min_range - margin) & (r <= self.max_range + margin)
        if self.sector_width < TWO_PI:
            frac = self.sector_fraction(pos, polar)
            ang = np.minimum(margin / np.maximum(r, 1.0), np.pi) / self.sector_width
            ok &= (frac >= -ang) & (frac <= 1.0 + ang)
        if self.polygon is not None and ok.any():
            rows = np.flatnonzero(ok)
            ok[rows] = signed_distance(self._plane(pos[rows]), self.polygon) >= -margin[rows]
        return ok

    def illumination_time(self, pos: np.ndarray, polar=None) -> np.ndarray:
        """Time (ns) the beam swept each position: linear in azimuth across the sector."""
        frac = np.clip(self.sector_fraction(np.atleast_2d(pos), polar), 0.0, 1.0)
        span = self.time_end - self.time_start
        return self.time_start + np.round(frac * span).astype(np.int64)


@dataclass
class MeasurementBatch:
    """One batch of plots in the system frame.

    time_ns: batch time (ns UTC; the end of the sector sweep);
    radar_id: the sensor; z (m, k): positions, m; R (m, k, k) or (k, k): covariances, m²;
    p_detection: P_D of that sensor; clutter_density: false plots per m² (per m³ in 3-D)
    per scan, scalar or (m,) per plot; coverage: which tracks could have been detected
    (None: every track); plot_times (m,) ns (optional); plot_ids, target_ids (m,)
    optional, for evaluation only (never used to associate); heights (m,) m above the
    ellipsoid (the reported flight level of 2-D radars, NaN: unknown; optional), used only
    for the coverage (the cone of silence of the tracks' last plots); identity (optional):
    the plots' secondary-surveillance columns (:class:`~.identity.PlotIdentity`), only
    ever attributed to the tracks that took the plots, never used to associate."""

    time_ns: int
    radar_id: str
    z: np.ndarray
    R: np.ndarray
    p_detection: float
    clutter_density: float | np.ndarray = 0.0
    coverage: SectorCoverage | None = None
    plot_times: np.ndarray | None = None
    plot_ids: np.ndarray | None = None
    target_ids: np.ndarray | None = None
    heights: np.ndarray | None = None
    identity: PlotIdentity | None = None
    rejected: dict[str, int] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.z)

    def validated(self, ndim: int) -> MeasurementBatch:
        """A copy with arrays in canonical shape and bad plots dropped; the reasons are
        counted in ``rejected``. Raises ValueError for batch-level problems."""
        z, R, rho = self._canonical(ndim)
        m = len(z)
        if self.heights is not None and np.shape(self.heights) != (m,):
            raise ValueError(f"heights has shape {np.shape(self.heights)}: expected ({m},)")
        if self.identity is not None and len(self.identity) != m:
            raise ValueError(f"identity has {len(self.identity)} plots: expected {m}")
        rejected = dict(self.rejected)
        # one pass over the whole batch first: a clean batch (the usual case) skips the
        # per-reason masks (the same result: every plot kept, nothing counted)
        c = np.ascontiguousarray
        clean = all_plots_valid(c(z), c(R), c(rho))
        ok = np.ones(m, dtype=bool) if clean else self._plot_mask(z, R, rho, rejected)

        def sel(a):
            return None if a is None else np.asarray(a)[ok]

        return replace(
            self,
            z=z[ok],
            R=R[ok],
            clutter_density=rho[ok],
            plot_times=sel(self.plot_times),
            plot_ids=sel(self.plot_ids),
            target_ids=sel(self.target_ids),
            heights=None if self.heights is None else np.asarray(self.heights, float)[ok],
            identity=self.identity if clean or self.identity is None else self.identity.take(ok),
            rejected=rejected,
        )

    def _canonical(self, ndim: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """z (m, ndim), R (m, ndim, ndim), clutter density (m,) as float arrays; raises
        ValueError for a bad P_D or shapes."""
        if not 0.0 < float(self.p_detection) <= 1.0:
            raise ValueError(f"p_detection = {self.p_detection}: must be in (0, 1]")
        z = (
            np.asarray(self.z, dtype=np.float64).reshape(-1, ndim)
            if np.size(self.z)
            else (np.zeros((0, ndim)))
        )
        m = len(z)
        R = np.asarray(self.R, dtype=np.float64)
        if R.shape == (ndim, ndim):
            R_all = np.empty((m, ndim, ndim))
            R_all[:] = R
            R = R_all
        if R.shape != (m, ndim, ndim):
            raise ValueError(f"R has shape {R.shape}: expected ({m}, {ndim}, {ndim}) or 2-D")
        rho = np.asarray(self.clutter_density, dtype=np.float64)
        rho = np.full(m, float(rho)) if rho.ndim == 0 else rho
        if rho.shape != (m,):
            raise ValueError(f"clutter_density has shape {rho.shape}: expected () or ({m},)")
        return z, R, rho

    @staticmethod
    def _plot_mask(
        z: np.ndarray, R: np.ndarray, rho: np.ndarray, rejected: dict[str, int]
    ) -> np.ndarray:
        """The plots that pass every test, each rejection counted under its first failed
        test's reason in ``rejected``."""
        m, ndim = z.shape
        ok = np.ones(m, dtype=bool)

        def reject(mask: np.ndarray, reason: str) -> None:
            bad = mask & ok
            if bad.any():
                rejected[reason] = rejected.get(reason, 0) + int(bad.sum())
                ok[bad] = False

        reject(~np.isfinite(z).all(axis=1), "position not finite")
        reject(~np.isfinite(R).all(axis=(1, 2)), "covariance not finite")
        reject(~np.isfinite(rho) | (rho < 0), "clutter density negative or not finite")
        # the rejected plots' R replaced by I for the next tests (none in a clean batch)
        Rs = R if ok.all() else np.where(ok[:, None, None], R, np.eye(ndim))
        asym = np.abs(Rs - Rs.swapaxes(1, 2)).max(axis=(1, 2), initial=0.0) > 1e-6 * (
            1.0 + np.abs(Rs).max(axis=(1, 2), initial=0.0)
        )
        reject(asym, "covariance not symmetric")
        Rs = Rs if ok.all() else np.where(ok[:, None, None], Rs, np.eye(ndim))
        reject(~positive_definite(Rs), "covariance not positive definite")
        return ok
