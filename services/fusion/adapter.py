"""Radar plots converted by :func:`fusion.frames.convert_plots` → :class:`MeasurementBatch`.

The sensor model the tracker needs comes from the radar's :class:`schemas.RadarSite`
(P_D, nominal clutter density, instrumented range) and the :class:`schemas.PlotBatch`
(swept sector, sweep times, evaluation ``target_id``); positions and covariances come
from the conversion. The coverage carries the radar's cone of silence: the site height
and its maximum elevation (a ``max_elevation`` field of the site, rad, when the schema
has one; otherwise :data:`~skyfuse.fusion.tracker.measurements.DEFAULT_MAX_ELEVATION`
for rotating radars, none for cartesian sensors), and the batch carries the plots'
reported altitudes as their heights, and their secondary-surveillance columns, when
the batch has any, as their identity (:func:`~skyfuse.fusion.tracker.identity
.plot_identity`: what the tracker attributes to the tracks that take them, never used
to associate). Plots the conversion marked invalid are dropped and counted by reason in
``MeasurementBatch.rejected``.
"""

from __future__ import annotations

import functools
import re
from collections import Counter

import numpy as np
from skyfuse.fusion.tracker.identity import plot_identity
from skyfuse.fusion.tracker.measurements import (
    DEFAULT_MAX_ELEVATION,
    MeasurementBatch,
    SectorCoverage,
)
from skyfuse.schemas import Detection, PlotBatch, RadarKind, RadarSite

_PLOT_PREFIX = re.compile(r"^plot \d+: ")


def measurement_batch_from(
    converted,
    site: RadarSite,
    plot_batch: PlotBatch,
    frame=None,
    *,
    clutter_density: float | None = None,
    vertical_extent: float = 15_000.0,
    identity: bool = True,
) -> MeasurementBatch:
    """Build the tracker input from ``converted`` (a ``ConvertedPlots``: z, R, time, valid,
    reasons, site_position) of ``plot_batch`` measured by ``site``.

    clutter_density: override of ``site.clutter_density`` (plots per m² per scan). For
    3-D tracking the areal density is spread over ``vertical_extent`` metres of height to
    give a volume density. ``frame``: the system frame the plots were converted into,
    needed only for a site's coverage polygon (tracker axes are x east, y north in every
    frame). ``identity``: whether the tracker attributes identity (``TrackerConfig.
    identity``); without it the plots' identity view is not built."""
    valid = np.asarray(converted.valid, dtype=bool)
    ndim = converted.z.shape[1]
    rho = float(site.clutter_density if clutter_density is None else clutter_density)
    if ndim == 3:
        rho /= vertical_extent
    rejected = Counter(
        _PLOT_PREFIX.sub("", converted.reasons[i]) or "invalid" for i in np.flatnonzero(~valid)
    )
    tid = plot_batch.column("target_id")
    coverage = _coverage(converted, site, plot_batch, frame)
    alt = plot_batch.column("altitude")
    ident = plot_identity(plot_batch.column) if identity else None  # None: no columns
    return MeasurementBatch(
        time_ns=int(plot_batch.time_end),
        radar_id=site.radar_id,
        z=converted.z[valid],
        R=converted.R[valid],
        p_detection=site.p_detection,
        clutter_density=rho,
        coverage=coverage,
        plot_times=np.asarray(converted.time, dtype=np.int64)[valid],
        plot_ids=np.flatnonzero(valid),
        target_ids=None if tid is None else tid[valid],
        heights=_heights(alt, plot_batch, site, valid),
        identity=None if ident is None else ident.take(valid),
        rejected=dict(rejected),
    )


def _coverage(converted, site: RadarSite, plot_batch: PlotBatch, frame) -> SectorCoverage:
    """A rotating radar sweeps the sector from time_start to time_end, so each track is
    predicted to the time the beam crossed it (``timing = "sweep"``); a cartesian sensor
    measures all at once; a report-based sensor (and a polar sensor with ``timing =
    "plots"``) predicts each track to the time of the plot nearest to it. The site's
    polygon, ceiling and detection semantics go with it (docs/concepts/sensors.md)."""
    rotating = site.kind in (RadarKind.TWO_D, RadarKind.THREE_D)
    reports = site.detection is Detection.REPORTS
    plots = reports or site.timing == "plots"
    sweep = rotating and not plots
    return SectorCoverage(
        site=np.asarray(converted.site_position, dtype=np.float64),
        min_range=site.min_range,
        max_range=site.max_range,
        sector_start=plot_batch.sector_start,
        sector_width=plot_batch.sector_width,
        time_start=plot_batch.time_start if sweep else plot_batch.time_end,
        time_end=plot_batch.time_end,
        max_elevation=getattr(site, "max_elevation", DEFAULT_MAX_ELEVATION) if sweep else None,
        site_height=float(site.alt),
        polygon=None if site.coverage is None else coverage_polygon(frame, site.coverage),
        max_height=site.max_altitude,
        timing="plots" if plots else "sweep",
        detection="reports" if reports else "sweep",
        report_timeout=site.report_timeout,
    )


def _heights(alt, plot_batch: PlotBatch, site: RadarSite, valid) -> np.ndarray | None:
    """The plots' heights for the coverage: the altitude column, else, for cartesian and
    WGS-84 sensors, the site's height for plots reported on the ground (``flight_status`` 1
    or 3: the ADS-B and multilateration ground bit)."""
    status = None if site.kind in (RadarKind.TWO_D, RadarKind.THREE_D) else (
        plot_batch.column("flight_status")
    )  # fmt: skip
    ground = None if status is None else (status == 1) | (status == 3)
    if ground is None or not ground.any():
        return None if alt is None else np.asarray(alt, dtype=np.float64)[valid]
    h = np.full(len(plot_batch), np.nan) if alt is None else np.asarray(alt, np.float64).copy()
    h[ground & ~np.isfinite(h)] = site.alt
    return h[valid]


@functools.lru_cache(maxsize=256)
def _polygon_cached(frame, vertices: tuple) -> np.ndarray:
    lat, lon = np.array(vertices, dtype=np.float64).T
    x, y, _ = frame.from_geodetic(lat, lon, np.zeros_like(lat))
    out = np.column_stack([x, y])
    out.flags.writeable = False
    return out


def coverage_polygon(frame, vertices) -> np.ndarray:
    """A site's coverage polygon (WGS-84 [lat, lon] vertices) in ``frame``'s plane (V, 2)
    (x east, y north), cached by frame and vertices."""
    if frame is None:
        raise ValueError("a coverage polygon needs the system frame")
    return _polygon_cached(frame, tuple(tuple(v) for v in vertices))
