"""The tracker's out-of-sequence pass: a batch whose illumination time of a track is
older than the track's current time t_k updates that track through the OOSM update
(Bar-Shalom 2002, A1: :mod:`.oosm`; the densities' :class:`~.density.base.Retrodiction`)
instead of meeting its newer state.

Per batch (:meth:`OutOfSequence.split` before the ordinary step, :meth:`apply` after):

1. **Split.** Of the tracks in coverage, those whose illumination time τ (the batch time,
   or the sweep time at the track's position, as in :mod:`.coverage`) is before their
   t_k are *late rows*; the others take the ordinary prediction-update step.
2. **Retrodiction and gating.** The density retrodicts each late row to τ (the lag
   Δ = t_k − τ per track, ``retrodict``) and the batch's plots are gated and weighed
   against that with the density's ``likelihoods`` (one gate, one table).
3. **Association and existence.** The configured association part (IPDA/ITS single, LM,
   joint, GNN) on that table with the clutter density of the batch, exactly as the
   ordinary step, with the tracks' current existence-chain state as the prior (no
   prediction: the existence transition over Δ ≤ max_lateness is neglected,
   Δ11^{Δ/T} ≈ 1) and the chain update with the association's ψ_det' ([thesis] 5.18,
   6.7). The late rows and the ordinary rows are associated separately (one plot can be
   weighed by both sets; in a lagging radar's batch nearly all tracks are late).
4. **Update.** The density's ``update_late``; t_k stays (the posterior is still at
   t_k); the hit counters as in the ordinary step, with last_update = max(last_update, τ).

The pass works through the density's protocol and the tracker's :class:`~.phases.Phases`
(association, hit counters, plots taken), never the tracker itself. A density whose
``late_plots`` is ``"current"`` (particles) has no retrodiction: its late plots are
applied at the tracks' current time by the ordinary step, counted as
``oosm_unsupported``.

**Initiation.** Plots that no late or ordinary track takes start tracks at their own time
like any plot (one-point; two-point pairs only with older buffered plots, Δt ≥
init_min_dt), so a radar that always lags still starts the tracks only it sees.

**Memory.** The prior of every track's last ordinary update, per mode and track-level
(the density's ``track_priors``), and its time: columns ``oosm_t`` (n,) ns (−1: none
yet), ``oosm_x{j}`` (n, d_j), ``oosm_P{j}`` (n, d_j, d_j) of the track store (one row per
track: they leave with their track), written by :meth:`record` after each ordinary
update. A row's prior is used only while its time is the track's t_k.
"""

from __future__ import annotations

import numpy as np

from .oosm import NS
from .store import Column, ColumnGroup


class OutOfSequence:
    """The OOSM part of one tracker (see the module docstring); ``enabled`` when the
    configuration asks for it and the density retrodicts. tracks: the track store (the
    memory columns are declared in it when enabled)."""

    def __init__(self, density, tracks, enabled: bool) -> None:
        self.density, self.tracks = density, tracks
        self.enabled = bool(enabled) and density.late_plots == "retrodict"
        self.modes = len(density.mode_dims) if self.enabled else 0
        self._names = [(f"oosm_x{j}", f"oosm_P{j}") for j in range(self.modes)]
        if self.enabled:
            cols = [Column("oosm_t", np.int64, fill=-1, doc="time of the last prior, ns")]
            for j, d in enumerate(density.mode_dims):
                cols.append(Column(f"oosm_x{j}", np.float64, (d,), fill=0.0, doc="prior"))
                cols.append(Column(f"oosm_P{j}", np.float64, (d, d), fill=0.0, doc="its cov."))
            tracks.declare(ColumnGroup("out-of-sequence", tuple(cols)))

    def split(self, sel: np.ndarray, t_sweep: np.ndarray, stats: dict):
        """(ordinary rows, late rows, τ (n,) ns) of the tracks ``sel`` in coverage, with
        τ the batch's sweep time at each track (``t_sweep``, :mod:`.coverage`)."""
        t_tau = t_sweep
        late_mask = t_tau[sel] < self.tracks.t_last[sel]
        if not late_mask.any():
            return sel, sel[:0], t_tau
        if not self.enabled:
            stats["oosm_unsupported"] = int(late_mask.sum())
            return sel, sel[:0], t_tau
        return sel[~late_mask], sel[late_mask], t_tau

    def record(self, rows: np.ndarray, t: np.ndarray, pred) -> None:
        """Store the track-level priors of ``pred`` for the tracks ``rows`` updated at
        ``t`` (n,) ns."""
        if not self.enabled or len(rows) == 0:
            return
        xs, Ps = self.density.track_priors(pred)
        tr = self.tracks
        tr.oosm_t[rows] = t[rows]
        for j, (x_name, P_name) in enumerate(self._names):
            getattr(tr, x_name)[rows] = xs[j]
            getattr(tr, P_name)[rows] = Ps[j]

    def _priors(self, rows: np.ndarray):
        """(known (s,), x[j] (s, d_j), P[j]) of the rows: known where the stored prior is
        the one of the track's current time."""
        tr = self.tracks
        known = tr.oosm_t[rows] == tr.t_last[rows]
        xs = [getattr(tr, x_name)[rows] for x_name, _ in self._names]
        return known, xs, [getattr(tr, P_name)[rows] for _, P_name in self._names]

    def apply(self, phases, b, late, t_tau, share, bit, assigned, used, stats):
        """The OOSM update of the late rows ``late`` (sorted) by batch ``b``; returns
        ``assigned`` (n,) and ``used`` (m,) with the late rows' plots added (see the
        module docstring). share: detection shares by row; bit: the radar's mask bit."""
        tr, density = self.tracks, self.density
        lag = (tr.t_last[late] - t_tau[late]) * NS
        priors = self._priors(late)
        pred = density.retrodict(late, lag, priors)
        table = density.likelihoods(pred, b.z, b.R, phases.g)
        exist = tr.exist[late]
        res = phases.associate(b, pred, table, exist[:, 0], share[late])
        density.update_late(pred, table, res.beta0, res.beta)
        tr.exist[late] = phases.chain.update(exist, res.psi_post)
        hits = phases.record_hits(late, np.maximum(tr.last_update, t_tau), res, table, bit)
        phases.attribute(b, late, res, table)
        taken = hits >= 0
        assigned = np.where(taken, hits, assigned)
        used = used | phases.used_plots(len(b), table, res)
        stats["oosm_tracks"] = len(late)
        stats["oosm_gated_pairs"] = len(table.tp_track)
        stats["oosm_plots"] = len(np.unique(table.tp_plot))
        stats["oosm_prior_known"] = int(priors[0].sum())
        stats["oosm_hits"] = int(taken.sum())
        return assigned, used
