"""IPDA / ITS track-level existence and association probabilities ([thesis] §2.3.1, ch. 5).

Works on the *track–plot table*: one row per (track, plot) pair where at least one
component of the track gated the plot, with the track likelihood p^τ_i = Σ_c ξ^c p^c_i
(5.10) and the clutter density ρ_i the track should use. All functions are vectorised
over tracks; ``tp_track`` gives each row's track (0..n−1).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np


@dataclass
class AssociationResult:
    """Posterior existence ψ_det' (n,), β_0 (n,) per track, β_i per track–plot row, and
    counters (e.g. JIPDA clusters that fell back to LM)."""

    psi_post: np.ndarray
    beta0: np.ndarray
    beta: np.ndarray
    stats: dict[str, int] = field(default_factory=dict)


def likelihood_ratio(pdpg: np.ndarray, ratio_sum: np.ndarray) -> np.ndarray:
    """Λ_k = 1 − P_D P_G + P_D P_G Σ_i p_{k,i}/ρ_{k,i} (5.16; 2.39 with Λ = 1 − δ).
    With no plot in the gate the sum is 0 and Λ = 1 − P_D P_G."""
    return 1.0 - pdpg + pdpg * ratio_sum


def existence_update(psi_pred: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """ψ_{k|k} = Λ ψ_{k|k−1} / (1 − (1 − Λ) ψ_{k|k−1}) (5.18, ≡ 2.41)."""
    return lam * psi_pred / (1.0 - (1.0 - lam) * psi_pred)


def estimated_clutter_density(
    m: np.ndarray, pdpg: np.ndarray, psi_pred: np.ndarray, volume: np.ndarray, floor: float
) -> np.ndarray:
    """Non-parametric clutter (2.35 corrected): m̂ = m − P_D P_G ψ_{k|k−1} if m > 0 else 0,
    ρ̂ = m̂ / V_k, floored at ``floor`` (plots per unit area)."""
    m_hat = np.where(m > 0, m - pdpg * psi_pred, 0.0)
    return np.maximum(m_hat / np.maximum(volume, 1e-300), floor)


def plots_in_track_gate(
    d2: np.ndarray, tp_track: np.ndarray, n: int, g: float, union_count: np.ndarray
) -> np.ndarray:
    """m_k of (2.35): per track, the track–plot rows inside the track-level gate
    V_k = {d̄² < g}, d̄² of each row from the track's moment-matched ȳ and S̄, the same
    region whose volume V_k divides m̂_k. Counting the union of the component gates
    instead (plots only a weak, wide component reaches) overstates ρ̂ (docs/reproduction.md). A track
    whose rows all lie outside V_k keeps ``union_count`` (its m over the union)."""
    inside = np.bincount(tp_track[d2 < g], minlength=n)
    return np.where(inside > 0, inside, union_count)


def single_target(
    psi_pred: np.ndarray,
    pdpg: np.ndarray,
    tp_track: np.ndarray,
    ratio: np.ndarray,
) -> AssociationResult:
    """IPDA/ITS update of independent tracks from ratios p^τ_i/ρ_i per table row.

    Λ (5.16), ψ (5.18), β_0 = (1 − P_D P_G)/Λ and β_i = P_D P_G (p_i/ρ_i)/Λ (2.38), so
    that the ITS component weights are ξ^{c,0} = β_0 ξ^c, ξ^{c,i} = β_i ξ^c p^c_i/p_i (5.15).
    One compiled pass (:func:`single_target_arrays`)."""
    c = np.ascontiguousarray
    f = np.float64
    return AssociationResult(*single_target_arrays(
        c(psi_pred, dtype=f), c(pdpg, dtype=f), c(tp_track, dtype=np.int64), c(ratio, dtype=f)
    ))  # fmt: skip


@numba.njit(cache=True, nogil=True, error_model="numpy")  # x/0 as in NumPy
def single_target_arrays(psi_pred, pdpg, tp_track, ratio):
    """(ψ_det', β₀, β) of :func:`single_target`: the sums Σ_i p_i/ρ_i in row order, then
    :func:`likelihood_ratio`, :func:`existence_update` and β as written there."""
    n = len(psi_pred)
    ratio_sum = np.zeros(n)
    for r in range(len(ratio)):
        ratio_sum[tp_track[r]] += ratio[r]
    psi_post, beta0 = np.empty(n), np.empty(n)
    lam = np.empty(n)
    for k in range(n):
        lam[k] = 1.0 - pdpg[k] + pdpg[k] * ratio_sum[k]
        psi_post[k] = lam[k] * psi_pred[k] / (1.0 - (1.0 - lam[k]) * psi_pred[k])
        beta0[k] = (1.0 - pdpg[k]) / lam[k]
    beta = np.empty(len(ratio))
    for r in range(len(ratio)):
        t = tp_track[r]
        beta[r] = pdpg[t] * ratio[r] / lam[t]
    return psi_post, beta0, beta
