"""Posterior Cramér–Rao floor under the RMSE curves of the Monte Carlo evaluation
(Tichavský's bound, Tichavský et al. 1998; docs/reports/particles-log.md, used as the
floor under RMSE).

For every target of every run the bound is computed along its own life (its *age*: the
number of scans since it first appears in the truth, 1 at its first scan) with the
scenario's linear-Gaussian model, :func:`fusion.particles.pcrlb.linear_gaussian`:

* motion: CV, x = [x, vx, y, vy] (m, m/s), F(T), Q_T = Γ q Γᵀ with the **truth's** process
  noise q of the scenario (m²/s⁴; thesis-stt 0.75, the straight-line thesis-mtt / lm-ipf
  trajectories q = 0), T the scan period (s);
* measurement: z = Hx + e, R = σ² I (m²) of the scenario's sensor;
* missed detections: information reduction factor P_D on HᵀR⁻¹H (the module docstring of
  ``pcrlb``; with clutter the true factor is smaller, so the floor stays valid, looser);
* prior [IMPL]: diffuse, P_0 = ``PRIOR_VARIANCE`` · I. No tracker knows the target before
  its first plot (the thesis-mtt velocity randomisation and the fixed lm-ipf trajectories
  are not given to the trackers), so the bound is that of an estimator starting from
  nothing; with P_D = 1, q = 0 it is the least-squares line fit, position variance
  2σ²(2k − 1)/(k(k + 1)) per axis after k scans.

The bound of a truth row is B = tr(position block of J_age⁻¹) (m²). Two curves per scan:

* ``pcrlb_m``: √(mean B over the rows the RMSE averages), the floor of the evaluation's
  RMSE of confirmed true tracks (same rows: confirmed, labelled true, target present),
  computed by :func:`fusion.metrics.mtt_measures.rmse_confirmed_true` itself on zero
  track positions and truth positions (√B, 0), so the rows are matched by one mechanism;
* ``pcrlb_targets_m``: √(mean B over all targets present), the floor of any estimator.

The RMSE's rows are **selected**: a track is confirmed and labelled true mostly after
plots in every scan, so in the first scans after initiation its rows come from detection
sequences with more information than the P_D-averaged bound assumes, and the RMSE can
fall below ``pcrlb_m`` there (measured: down to 0.87 × at scans 4–6 on thesis-mtt-5/15
and lm-ipf-15, P_D = 0.8). ``summary`` therefore also writes ``pcrlb_all_detected_m``,
the same curve with P_D = 1 (a plot in every scan): the floor for any detection
sequence, so for any selection of rows by their detections. (The labelling selects by
the error as well; with its χ² gate this truncates only the far tail.)
"""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.metrics.history import TrackHistory, TruthHistory
from skyfuse.fusion.metrics.mtt_measures import rmse_confirmed_true
from skyfuse.fusion.models import ConstantVelocity
from skyfuse.fusion.particles import pcrlb
from skyfuse.fusion.sim import build_scenario

from .experiment import run_seed

#: Diffuse prior variance of every state component (m², m²/s²) [IMPL].
PRIOR_VARIANCE = 1e8


def position_bound_by_age(
    ages: int, period: float, q: float, sigma2: float, p_detection: float
) -> np.ndarray:
    """B(k) for k = 1..ages (m²): trace of the position block of the PCRLB after k scans
    of the planar CV model (module docstring)."""
    cv = ConstantVelocity(q=float(q), ndim=2)
    F, Q, H = cv.F(float(period)), cv.Q(float(period)), cv.H()
    P0 = PRIOR_VARIANCE * np.eye(cv.dim)
    R = float(sigma2) * np.eye(2)
    P = pcrlb.linear_gaussian(
        P0, F, Q, H, R, int(ages), form="information", information_factor=float(p_detection)
    )
    pos = list(cv.position_index)
    return np.trace(P[:, pos][:, :, pos], axis1=1, axis2=2)


def truth_ages(truth: TruthHistory) -> np.ndarray:
    """Age of every truth row (1 at the target's first scan in its run, +1 per later row)."""
    order = np.lexsort((truth.scan, truth.target_id, truth.run))
    run, tid = truth.run[order], truth.target_id[order]
    new = np.ones(len(order), bool)
    new[1:] = (run[1:] != run[:-1]) | (tid[1:] != tid[:-1])
    start = np.maximum.accumulate(np.where(new, np.arange(len(order)), 0))
    ages = np.empty(len(order), np.int64)
    ages[order] = np.arange(len(order)) - start + 1
    return ages


def pcrlb_curves(
    tracks: TrackHistory,
    truth: TruthHistory,
    scans: np.ndarray,
    bound_by_age: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(``pcrlb_m``, ``pcrlb_targets_m``) per scan, m, NaN where there are no rows.

    ``bound_by_age``: B(k) for k = 1..K (:func:`position_bound_by_age`), K ≥ the largest
    age in ``truth``."""
    ages = truth_ages(truth)
    if len(ages) and ages.max() > len(bound_by_age):
        raise ValueError(
            f"bound_by_age: {len(bound_by_age)} ages, the truth has targets of age "
            f"{int(ages.max())}"
        )
    b = np.asarray(bound_by_age, float)[ages - 1] if len(ages) else np.zeros(0)
    as_pos = np.column_stack([np.sqrt(b), np.zeros_like(b)])
    floor_truth = TruthHistory(truth.run, truth.scan, truth.target_id, as_pos)
    zero_tracks = TrackHistory(
        tracks.run, tracks.scan, tracks.track_id, tracks.confirmed, tracks.label,
        np.zeros((len(tracks), 2)), tracks.existence,
    )  # fmt: skip
    on_rows, _ = rmse_confirmed_true(zero_tracks, floor_truth, scans)
    scans = np.asarray(scans, np.int64)
    idx = np.searchsorted(scans, truth.scan)
    ok = idx < len(scans)
    ok[ok] = scans[idx[ok]] == truth.scan[ok]
    n = np.bincount(idx[ok], minlength=len(scans))
    s = np.bincount(idx[ok], weights=b[ok], minlength=len(scans))
    with np.errstate(invalid="ignore", divide="ignore"):
        all_targets = np.where(n > 0, np.sqrt(s / np.maximum(n, 1)), np.nan)
    return on_rows, all_targets


def scenario_bound_model(exp) -> dict[str, float]:
    """The bound's model of an :class:`~fusion.evaluation.Experiment`'s scenario: truth
    process noise q (m²/s⁴; 0 when the scenario has none), σ² (m²), P_D, scan period T (s),
    and the prior variance (module docstring)."""
    sc = build_scenario(exp.scenario, seed=run_seed(exp.seed, 0), **exp.scenario_params)
    site = sc.sites[0]
    return {
        "q": float(sc.params.get("q", 0.0)),
        "sigma2": float(site.sigma_cartesian) ** 2,
        "p_detection": float(site.p_detection),
        "period": float(site.scan_period),
        "prior_variance": PRIOR_VARIANCE,
    }
