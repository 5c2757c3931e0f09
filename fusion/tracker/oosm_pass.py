"""The tracker's out-of-sequence pass: a batch whose illumination time of a track is
older than the track's current time t_k updates that track through the OOSM update
(:mod:`.oosm`, :mod:`.oosm_density`) instead of meeting its newer state.

Per batch (:meth:`OutOfSequence.split` before the ordinary step, :meth:`apply` after):

1. **Split.** Of the tracks in coverage, those whose illumination time τ (the batch time,
   or the sweep time at the track's position, as in :mod:`.coverage`) is before their
   t_k are *late rows*; the others take the ordinary prediction-update step.
2. **Retrodiction and gating.** Each late row's components are retrodicted to τ (the
   lag Δ = t_k − τ per track) and the batch's plots are gated and weighed against them
   with the density's ``likelihoods`` (one gate, one table).
3. **Association and existence.** The configured association part (IPDA/ITS single, LM,
   joint, GNN) on that table with the clutter density of the batch, exactly as the
   ordinary step, with the tracks' current existence-chain state as the prior (no
   prediction: the existence transition over Δ ≤ max_lateness is neglected,
   Δ11^{Δ/T} ≈ 1) and the chain update with the association's ψ_det' (5.18, 6.7). The
   late rows and the ordinary rows are associated separately (one plot can be weighed
   by both sets; in a lagging radar's batch nearly all tracks are late).
4. **Update.** :func:`~.oosm_density.oosm_children` and the density's ``store_children``;
   t_k stays (the posterior is still at t_k); the hit counters as in the ordinary step,
   with last_update = max(last_update, τ).

**Initiation.** Plots that no late or ordinary track takes start tracks at their own time
like any plot (one-point; two-point pairs only with older buffered plots, Δt ≥
init_min_dt), so a radar that always lags still starts the tracks only it sees.

**Memory.** The prior of every track's last ordinary update (per mode, track-level) is
kept in a :class:`~.oosm.LastStep` store keyed by track id (bounded by the live tracks),
recorded by :meth:`record` after each ordinary update.
"""

from __future__ import annotations

import numpy as np

from .oosm import NS, LastStep
from .oosm_density import mode_dims, oosm_children, retrodict_density, supported, track_priors


class OutOfSequence:
    """The OOSM part of one :class:`~fusion.tracker.tracker.Tracker` (see the module
    docstring); ``enabled`` when the configuration asks for it and the density has the
    OOSM update (Gaussian mixture, IMM; not particles)."""

    def __init__(self, density, enabled: bool) -> None:
        self.enabled = bool(enabled) and supported(density)
        self.last = LastStep.empty(mode_dims(density) if supported(density) else [1])

    def split(self, tracker, sel: np.ndarray, t_sweep: np.ndarray, stats: dict):
        """(ordinary rows, late rows, τ (n,) ns) of the tracks ``sel`` in coverage, with
        τ the batch's sweep time at each track (``t_sweep``, :mod:`.coverage`)."""
        t_tau = t_sweep
        late_mask = t_tau[sel] < tracker.t_last[sel]
        if not late_mask.any():
            return sel, sel[:0], t_tau
        if not self.enabled:
            stats["oosm_unsupported"] = int(late_mask.sum())
            return sel, sel[:0], t_tau
        return sel[~late_mask], sel[late_mask], t_tau

    def record(self, tracker, rows: np.ndarray, t: np.ndarray, pred) -> None:
        """Store the track-level priors ``pred`` of the tracks ``rows`` updated at t."""
        if not self.enabled or len(rows) == 0:
            return
        xs, Ps = track_priors(pred)
        self.last.record(tracker.ids[rows], t[rows], xs, Ps, tracker.ids)

    def apply(self, tracker, b, late, t_tau, share, bit, assigned, used, stats):
        """The OOSM update of the late rows ``late`` (sorted); returns ``assigned``
        (n,) and ``used`` (m,) with the late rows' plots added (see the module docstring)."""
        lag = (tracker.t_last[late] - t_tau[late]) * NS
        priors = self.last.lookup(tracker.ids[late], tracker.t_last[late])
        density = tracker.density
        pred, cur, Cs = retrodict_density(density, late, lag, priors)
        table = density.likelihoods(pred, b.z, b.R, tracker.g)
        exist = tracker.exist[late]
        res = tracker._associate(b, pred, table, exist[:, 0], share[late])
        children = oosm_children(density, pred, cur, Cs, table, res.beta0, res.beta)
        density.store_children(late, children, len(table.tp_track))
        tracker.exist[late] = tracker.chain.update(exist, res.psi_post)
        hits = tracker._record_hits(late, np.maximum(tracker.last_update, t_tau), res, table, bit)
        taken = hits >= 0
        assigned = np.where(taken, hits, assigned)
        used = used | tracker._used_plots(len(b), table, res)
        stats["oosm_tracks"] = len(late)
        stats["oosm_gated_pairs"] = len(table.tp_track)
        stats["oosm_plots"] = len(np.unique(table.tp_plot))
        stats["oosm_prior_known"] = int(priors[0].sum())
        stats["oosm_hits"] = int(taken.sum())
        return assigned, used
