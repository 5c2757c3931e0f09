"""The steps of one batch that the ordinary update and the out-of-sequence pass share
(:mod:`.tracker`, :mod:`.oosm_pass`): association with the clutter density, the counters of
the tracks a plot detected, and the plots the tracks took. One small interface, so that
the out-of-sequence pass never reaches into the tracker.

* :meth:`Phases.associate`: the clutter density of every table row (:mod:`.clutter`,
  known or estimated, [thesis] 2.35) and the configured association part
  (:mod:`.associators`: IPDA/ITS [thesis] 5.16-5.18, LM 6.12-6.22, joint 6.1-6.8, GNN),
  with the detection probability P_D P_G of each track scaled by its detection share
  (:mod:`.coverage`);
* :meth:`Phases.record_hits`: a track whose plots weigh more than its "no plot"
  hypothesis (1 − β₀ > 0.5) counts a detection (updates, radar mask, last update time,
  the re-identification fix); each track's most likely plot of the batch;
* :meth:`Phases.attribute`: the identity of the plots with a weight above one half goes to
  their tracks (:mod:`.identity`);
* :meth:`Phases.used_plots`: the plots that may not start tracks.
"""

from __future__ import annotations

import numba
import numpy as np

from .associators import AssociationProblem
from .clutter import clutter_density
from .density.base import GatedTable, Prediction
from .ipda import AssociationResult
from .measurements import MeasurementBatch


class Phases:
    """The shared steps over the track store ``tracks`` (see the module docstring): cfg
    (``TrackerConfig``), chain (the existence chain), associate (the association part),
    g and P_G (gate threshold and probability), reid (the re-identification part or
    None), identity (the identity part or None)."""

    def __init__(self, cfg, tracks, chain, associate, g: float, P_G: float, reid,
                 identity=None) -> None:  # fmt: skip
        self.cfg, self.tracks, self.chain = cfg, tracks, chain
        self.associate_part, self.g, self.P_G, self.reid = associate, g, P_G, reid
        self.identity = identity

    def associate(
        self,
        b: MeasurementBatch,
        pred: Prediction,
        table: GatedTable,
        psi_det: np.ndarray,
        share: np.ndarray,
    ) -> AssociationResult:
        """Clutter density per row, then the configured association part; P_D of each
        row without a gated plot scaled by its detection ``share`` (a plot in the gate
        shows the radar saw where the track is)."""
        cfg = self.cfg
        share = share.copy()
        share[table.tp_track] = 1.0
        pdpg = float(b.p_detection) * self.P_G * share
        # the track-level moments only for the estimated clutter (known: not used)
        estimated = cfg.clutter == "estimated"
        rho = clutter_density(
            cfg.clutter,
            b.clutter_density,
            cfg.clutter_density_floor,
            table.tp_track,
            table.tp_plot,
            pred.S0 if estimated else None,
            b.R,
            pdpg,
            psi_det,
            self.g,
            z=b.z,
            z_mean=pred.z_mean if estimated else None,
            volume_floor=cfg.clutter_volume,
        )
        problem = AssociationProblem(
            psi_det,
            pdpg,
            table.tp_track,
            table.tp_plot,
            len(b),
            table.p,
            rho,
            cfg.lm_prior_density,
            cfg.jipda_max_events,
        )
        return self.associate_part(problem)

    def record_hits(
        self,
        sel: np.ndarray,
        t_pred: np.ndarray,
        res: AssociationResult,
        table: GatedTable,
        bit: int,
    ) -> np.ndarray:
        """Update counters of detected tracks (weight of a plot > 0.5) and return each
        track's most likely plot of the batch (−1: none, or β₀ larger)."""
        tr = self.tracks
        hit = sel[(1.0 - res.beta0) > 0.5]
        if self.cfg.life_cycle == "m_of_n":  # the M-of-N counters (:mod:`.management`)
            tr.scans[sel] += 1
            tr.misses[sel] += 1
            tr.misses[hit] = 0
        tr.updates[hit] += 1
        tr.radar_mask[hit] |= bit
        tr.last_update[hit] = t_pred[hit]
        if self.reid is not None and len(hit):
            self.reid.update_fixes(hit, t_pred[hit])
        c = np.ascontiguousarray
        return most_likely_plots(len(tr), c(sel, dtype=np.int64), c(res.beta0, dtype=np.float64),
                                 c(res.beta, dtype=np.float64), c(table.tp_track, dtype=np.int64),
                                 c(table.tp_plot, dtype=np.int64))  # fmt: skip

    def attribute(self, b: MeasurementBatch, rows: np.ndarray, res: AssociationResult,
                  table: GatedTable) -> None:  # fmt: skip
        """The identity of the plots whose weight β on a track of ``rows`` (the rows of
        the association) is above one half, to that track (:mod:`.identity`)."""
        if self.identity is None or b.identity is None or not len(res.beta):
            return
        strong = np.flatnonzero(res.beta > 0.5)
        plots = table.tp_plot[strong]
        t = b.time_ns if b.plot_times is None else b.plot_times[plots]
        t = np.broadcast_to(np.asarray(t, np.int64), plots.shape)
        self.identity.observe(b.identity, rows[table.tp_track[strong]], plots, t)

    def used_plots(self, m: int, table: GatedTable, res: AssociationResult) -> np.ndarray:
        """Plots that may not start tracks: gated by any track (``init_free_weight`` None),
        or claimed by the tracks with a total association weight Σ_τ β^τ_i of at least
        ``init_free_weight`` (a plot of a second, closely spaced target that a track gates
        but does not take can then start its own track)."""
        used = np.zeros(m, bool)
        if self.cfg.init_free_weight is None:
            used[table.tp_plot] = True
            return used
        claimed = np.bincount(table.tp_plot, weights=res.beta, minlength=m)
        return claimed >= self.cfg.init_free_weight


@numba.njit(cache=True, nogil=True)
def most_likely_plots(n, sel, beta0, beta, tp_track, tp_plot):
    """(n,) each track row's plot of largest β (the first of equal ones in table order;
    NaN last, as a sort would), −1 where none or where β₀ is not smaller."""
    assigned = np.full(n, -1, np.int64)
    best = np.full(len(sel), -1, np.int64)
    for r in range(len(beta)):
        t = tp_track[r]
        b = best[t]
        if b < 0 or -beta[r] < -beta[b] or (beta[b] != beta[b] and beta[r] == beta[r]):
            best[t] = r
    for t in range(len(sel)):
        b = best[t]
        if b >= 0 and beta[b] > beta0[t]:
            assigned[sel[t]] = tp_plot[b]
    return assigned
