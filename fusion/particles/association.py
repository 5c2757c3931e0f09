"""IPF association and the LM-IPF step over a gated table ([LM-IPF] eq. 10-17; the IPF of
[thesis] §3.4-3.6).

Inputs per gated (track, plot) row: the track likelihood p^τ_j ([LM-IPF] eq. 9, from
:meth:`ParticleDensity.likelihoods`, already divided by P_G), the plot's clutter density
ρ_j, and per track the predicted existence ψ_{k|k−1} (eq. 5) and P̃_D = P_D P_G (a
state-independent P_D, [thesis] 3.37, times the gate probability [LIT]).

* IPF (eq. 10-12, 17 with Ω = ρ): λ = 1 − P̃_D + P̃_D Σ_j p_j/ρ_j; β_0 = (1 − P̃_D)/λ,
  β_j = P̃_D (p_j/ρ_j)/λ; ψ_{k|k} = λ ψ / (1 − (1 − λ) ψ).
* LM-IPF: first, for *all* tracks from their predictions (Jacobi order, no joint events),
  the prior probability that plot j is track θ's detection (eq. 14, with P̃_D as in
  LM-IPDA) P^θ_j = P̃_D ψ^θ (p^θ_j/ρ_j) / Σ_{l∈sel(θ)} p^θ_l/ρ_l, then the modified
  clutter density (eq. 15 in the Mušicki–La Scala form; the paper's (15) mixes a
  likelihood with a probability and is corrected [TYPO])
  Ω^τ_j = ρ_j + Σ_{θ≠τ, j∈sel(θ)} p^θ_j P^θ_j / (1 − P^θ_j); then the IPF update with
  ρ → Ω (eq. 16-17, 12). A plot no other track selected gets Ω = ρ exactly, so far-apart
  tracks reduce to the IPF bit for bit.

The arithmetic is that of the Gaussian IPDA and LM-IPDA/LM-ITS ([thesis] 5.16–5.18,
6.12–6.14, "canonical" prior), so these functions are the tracker's association parts
``single`` and ``lm`` (:mod:`fusion.tracker.associators`) applied to the particle table:
one implementation of the existence and LM formulas, which the ``ipf`` / ``lmipf``
trackers use directly through the registry.
"""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.tracker.associators import AssociationProblem, associate_lm, associate_single
from skyfuse.fusion.tracker.density.particles import ParticleGatedTable
from skyfuse.fusion.tracker.ipda import AssociationResult
from skyfuse.fusion.tracker.lm_its import modified_clutter_density


def _problem(table, n_plots, psi_pred, pdpg, rho) -> AssociationProblem:
    psi, pdpg = np.asarray(psi_pred, float), np.asarray(pdpg, float)
    return AssociationProblem(psi, pdpg, table.tp_track, table.tp_plot, n_plots, table.p, rho)


def lm_clutter_density(
    table: ParticleGatedTable,
    n_plots: int,
    psi_pred: np.ndarray,
    pdpg: np.ndarray,
    rho: np.ndarray,
) -> np.ndarray:
    """Ω^τ_j per table row (eq. 14-15); ``rho`` per row, ``psi_pred``/``pdpg`` per track."""
    return modified_clutter_density(
        table.tp_track, table.tp_plot, n_plots, table.p, rho, psi_pred, pdpg, "canonical"
    )


def ipf_association(
    table: ParticleGatedTable, psi_pred: np.ndarray, pdpg: np.ndarray, clutter: np.ndarray
) -> AssociationResult:
    """ψ_{k|k}, β_0 (per track) and β_j (per row) by eq. 16, 17, 12; ``clutter`` per row is ρ_j
    (IPF) or Ω^τ_j (LM-IPF)."""
    return associate_single(_problem(table, 0, psi_pred, pdpg, np.asarray(clutter, float)))


def lm_ipf_association(
    table: ParticleGatedTable,
    n_plots: int,
    psi_pred: np.ndarray,
    pdpg: np.ndarray,
    rho: np.ndarray,
) -> AssociationResult:
    """LM-IPF: Ω for all tracks from the predictions first (eq. 14-15), then eq. 16, 17, 12."""
    return associate_lm(_problem(table, n_plots, psi_pred, pdpg, np.asarray(rho, float)))
