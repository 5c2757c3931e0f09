"""Feeding the registration from the tracker: :func:`observe_tracker_output` takes the
plots each track selected in one ``Tracker.step`` (``TrackerOutput.assigned_plot``) and
passes them, with the tracks' velocities, to the estimator.

Only plots of confirmed tracks (``config.confirmed_only``) that two or more radars have
updated (``TrackerOutput.radar_mask``), each assigned to one track only, at least
``config.min_ground_range`` from the radar (near the radar the position is poorly
conditioned), and valid polar conversions (``ConvertedPlots.polar_jacobian``) are used.
``out.batch.plot_ids`` must index ``converted`` rows (as the service adapter builds
them).
"""

from __future__ import annotations

import numpy as np

from .estimator import RegistrationEstimator


def _popcount(mask: np.ndarray) -> np.ndarray:
    """Radars per track: the set bits of the (non-negative, 63-bit) radar masks."""
    return np.bitwise_count(np.asarray(mask, np.int64))


def observe_tracker_output(est: RegistrationEstimator, out, converted, velocity_index) -> int:
    """Pass the plots ``out`` assigned to tracks to ``est``; returns the pairs used.

    ``out``: TrackerOutput of the step fed with ``converted`` (ConvertedPlots);
    ``velocity_index``: state indices of (vx, vy) (e.g. ``tracker.vel``)."""
    if converted.polar_jacobian is None or out.batch is None or out.batch.plot_ids is None:
        return 0
    rows = np.flatnonzero(out.assigned_plot >= 0)
    if est.cfg.confirmed_only:
        rows = rows[out.confirmed[rows].astype(bool)]
    rows = rows[_popcount(out.radar_mask[rows]) >= 2]
    plot = np.asarray(out.batch.plot_ids, np.int64)[out.assigned_plot[rows]]
    single = np.bincount(plot)[plot] == 1  # plots (converted rows) one track alone took
    rows, plot = rows[single], plot[single]
    z = converted.z[plot]
    ground = np.hypot(*(z[:, :2] - converted.site_position[:2]).T)
    ok = (ground >= est.cfg.min_ground_range) & np.isfinite(converted.polar_jacobian[plot]).all(
        axis=(1, 2)
    )
    rows, plot = rows[ok], plot[ok]
    z = z[ok]
    vi = np.asarray(velocity_index)[:2]
    # TrackerOutput predicts only the rows asked for; a plain record gives its arrays
    predicted = getattr(out, "predicted", None)
    x, P = predicted(rows)[:2] if predicted else (out.states[rows], out.covariances[rows])
    return (
        est.observe_plots(
            converted.radar_id,
            out.ids[rows],
            converted.time[plot],
            z,
            converted.R[plot],
            converted.polar_jacobian[plot],
            converted.slant_range[plot],
            x[:, vi],
            P[:, vi][:, :, vi],
            converted.bias,
        )
        if len(rows)
        else 0
    )
