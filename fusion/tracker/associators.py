"""Association parts of the existence trackers: each maps one
:class:`AssociationProblem` (the gated track × plot table with its likelihood ratios and
the predicted existence) to an :class:`~fusion.tracker.ipda.AssociationResult`
(posterior ψ_det, β₀ per track, β_i per table row).

* ``single`` — IPDA/ITS, independent tracks (5.16-5.18, 2.38): :mod:`.ipda`;
* ``lm`` — LM-IPDA/LM-ITS, other tracks as modulated clutter (6.11-6.22): :mod:`.lm_its`;
* ``joint`` — JIPDA/JITS, exact joint events per cluster with the LM fallback above
  ``max_events`` (6.1-6.10): :mod:`.jits`;
* ``gnn`` — the MAP joint event, one plot or none per track ([MZD] §5): :mod:`.gnn`.

The registry (:mod:`fusion.tracker.registry`) maps these names to the functions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .gnn import gnn_association
from .ipda import AssociationResult, single_target
from .jits import joint_association
from .lm_its import modified_clutter_density


@dataclass
class AssociationProblem:
    """psi (s,) predicted ψ_det per track; pdpg (s,) P_D P_G; tp_track, tp_plot (t,) the
    table; nplots: plots in the batch; p (t,) track likelihoods p^τ_i; rho (t,) clutter
    density each row's track uses; lm_prior: 'canonical' or 'thesis' (6.12-6.13);
    max_events: JIPDA cluster cap."""

    psi: np.ndarray
    pdpg: np.ndarray
    tp_track: np.ndarray
    tp_plot: np.ndarray
    nplots: int
    p: np.ndarray
    rho: np.ndarray
    lm_prior: str = "canonical"
    max_events: int = 5000

    @property
    def ratio(self) -> np.ndarray:
        """Likelihood ratios p^τ_i / ρ_i per row."""
        return self.p / self.rho


def associate_single(a: AssociationProblem) -> AssociationResult:
    """IPDA/ITS (5.16-5.18)."""
    return single_target(a.psi, a.pdpg, a.tp_track, a.ratio)


def associate_lm(a: AssociationProblem) -> AssociationResult:
    """LM-IPDA/LM-ITS: IPDA with the modified clutter density ρ̃ (6.14)."""
    rho_lm = modified_clutter_density(
        a.tp_track, a.tp_plot, a.nplots, a.p, a.rho, a.psi, a.pdpg, a.lm_prior
    )
    return single_target(a.psi, a.pdpg, a.tp_track, a.p / rho_lm)


def associate_joint(a: AssociationProblem) -> AssociationResult:
    """JIPDA/JITS (6.1-6.8), LM (6.14) for clusters above ``max_events``."""
    lm = associate_lm(a)
    return joint_association(
        a.psi, a.pdpg, a.tp_track, a.tp_plot, a.nplots, a.ratio, a.max_events, lm
    )


def associate_gnn(a: AssociationProblem) -> AssociationResult:
    """GNN with existence: the MAP joint event ([MZD] §5)."""
    return gnn_association(a.psi, a.pdpg, a.tp_track, a.tp_plot, a.nplots, a.ratio)
