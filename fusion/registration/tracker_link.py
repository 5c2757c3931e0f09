"""Feeding the registration from the tracker: :func:`observe_tracker_output` takes the
plots each track selected in one ``Tracker.step`` (``TrackerOutput.assigned_plot``) and
passes them, with the tracks' velocities, to the estimator.

Only plots of confirmed tracks (``config.confirmed_only``) that two or more sensors have
updated (``TrackerOutput.radar_mask``), each assigned to one track only, are used: a
radar's at least ``config.min_ground_range`` from the radar (near the radar the position
is poorly conditioned) with a valid polar conversion (``ConvertedPlots.polar_jacobian``);
a report sensor's (ADS-B, multilateration: no polar conversion, no bias model) only when
it is a named reference, with zero bias sensitivity (its positions are the datum), and
only its reports whose horizontal σ per axis is at most ``config.max_reference_sigma``
(ADS-B's σ from its NACp/NUCp: a poor report is not evidence of a radar's bias).
``out.batch.plot_ids`` must index ``converted`` rows (as the service adapter builds
them).
"""

from __future__ import annotations

import numpy as np

from .estimator import RegistrationEstimator


def _popcount(mask: np.ndarray) -> np.ndarray:
    """Radars per track: the set bits of the (non-negative, 63-bit) radar masks."""
    return np.bitwise_count(np.asarray(mask, np.int64))


def _usable_rows(est: RegistrationEstimator, out) -> tuple[np.ndarray, np.ndarray]:
    """(track rows, converted rows) of the plots of confirmed (``confirmed_only``) tracks
    that two or more sensors updated, each plot taken by one track alone."""
    rows = np.flatnonzero(out.assigned_plot >= 0)
    if est.cfg.confirmed_only:
        rows = rows[out.confirmed[rows].astype(bool)]
    rows = rows[_popcount(out.radar_mask[rows]) >= 2]
    plot = np.asarray(out.batch.plot_ids, np.int64)[out.assigned_plot[rows]]
    single = np.bincount(plot)[plot] == 1  # plots (converted rows) one track alone took
    return rows[single], plot[single]


def _sensitivity(est: RegistrationEstimator, converted, plot) -> tuple:
    """(usable mask, ∂z/∂(D, ψ) (k, 2, 2), slant range (k,)) of converted rows ``plot``: a
    polar radar's plots away from the radar with a valid Jacobian; a reference report
    sensor's (no bias model: zero sensitivity) of good enough quality."""
    if converted.polar_jacobian is None:
        k = len(plot)
        ok = est.reference_quality(converted.R[plot])
        return ok, np.zeros((k, converted.ndim, 2)), np.zeros(k)
    z = converted.z[plot]
    ground = np.hypot(*(z[:, :2] - converted.site_position[:2]).T)
    jac = converted.polar_jacobian[plot]
    ok = (ground >= est.cfg.min_ground_range) & np.isfinite(jac).all(axis=(1, 2))
    return ok, jac, converted.slant_range[plot]


def observe_tracker_output(est: RegistrationEstimator, out, converted, velocity_index) -> int:
    """Pass the plots ``out`` assigned to tracks to ``est``; returns the pairs used.

    ``out``: TrackerOutput of the step fed with ``converted`` (ConvertedPlots);
    ``velocity_index``: state indices of (vx, vy) (e.g. ``tracker.vel``). Plots of
    sensors without a polar conversion (ADS-B, multilateration) are used only when the
    sensor is a named reference (``config.reference``), and then only those within
    ``config.max_reference_sigma``."""
    if out.batch is None or out.batch.plot_ids is None:
        return 0
    if converted.polar_jacobian is None and not est.is_reference(converted.radar_id):
        return 0
    rows, plot = _usable_rows(est, out)
    ok, jac, slant = _sensitivity(est, converted, plot)
    rows, plot = rows[ok], plot[ok]
    if not len(rows):
        return 0
    vi = np.asarray(velocity_index)[:2]
    # TrackerOutput predicts only the rows asked for; a plain record gives its arrays
    predicted = getattr(out, "predicted", None)
    x, P = predicted(rows)[:2] if predicted else (out.states[rows], out.covariances[rows])
    return est.observe_plots(
        converted.radar_id,
        out.ids[rows],
        converted.time[plot],
        converted.z[plot],
        converted.R[plot],
        jac[ok],
        slant[ok],
        x[:, vi],
        P[:, vi][:, :, vi],
        converted.bias,
    )
