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

import re
from collections import Counter

import numpy as np
from skyfuse.fusion.tracker.identity import plot_identity
from skyfuse.fusion.tracker.measurements import (
    DEFAULT_MAX_ELEVATION,
    MeasurementBatch,
    SectorCoverage,
)
from skyfuse.schemas import PlotBatch, RadarKind, RadarSite

_PLOT_PREFIX = re.compile(r"^plot \d+: ")


def measurement_batch_from(
    converted,
    site: RadarSite,
    plot_batch: PlotBatch,
    frame=None,
    *,
    clutter_density: float | None = None,
    vertical_extent: float = 15_000.0,
) -> MeasurementBatch:
    """Build the tracker input from ``converted`` (a ``ConvertedPlots``: z, R, time, valid,
    reasons, site_position) of ``plot_batch`` measured by ``site``.

    clutter_density: override of ``site.clutter_density`` (plots per m² per scan). For
    3-D tracking the areal density is spread over ``vertical_extent`` metres of height to
    give a volume density. ``frame`` is accepted for symmetry with ``convert_plots`` (the
    converted plots are already in it; tracker axes are x east, y north in every frame)."""
    del frame
    valid = np.asarray(converted.valid, dtype=bool)
    ndim = converted.z.shape[1]
    rho = float(site.clutter_density if clutter_density is None else clutter_density)
    if ndim == 3:
        rho /= vertical_extent
    rejected = Counter(
        _PLOT_PREFIX.sub("", converted.reasons[i]) or "invalid" for i in np.flatnonzero(~valid)
    )
    tid = plot_batch.column("target_id")
    # A rotating radar sweeps the sector from time_start to time_end, so each track is
    # predicted to the time the beam crossed it; a cartesian sensor measures all at once.
    rotating = site.kind is not RadarKind.CARTESIAN
    coverage = SectorCoverage(
        site=np.asarray(converted.site_position, dtype=np.float64),
        min_range=site.min_range,
        max_range=site.max_range,
        sector_start=plot_batch.sector_start,
        sector_width=plot_batch.sector_width,
        time_start=plot_batch.time_start if rotating else plot_batch.time_end,
        time_end=plot_batch.time_end,
        max_elevation=getattr(site, "max_elevation", DEFAULT_MAX_ELEVATION) if rotating else None,
        site_height=float(site.alt),
    )
    alt = plot_batch.column("altitude")
    identity = plot_identity(plot_batch.column)  # None without secondary columns
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
        heights=None if alt is None else np.asarray(alt, dtype=np.float64)[valid],
        identity=None if identity is None else identity.take(valid),
        rejected=dict(rejected),
    )
