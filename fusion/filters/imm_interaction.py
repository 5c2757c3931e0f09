"""The interaction (mixing) step of the IMM, batched over n IMMs ([Dikić] eq. 15-17; the
IMM of Blom and Bar-Shalom, IEEE Trans. AC 33(8), 1988; [MZD] §3 uses it with two
PCWPA modes).

Each of n IMMs (a track, or a component of a track's mixture) has r modes with mode
probabilities μ_i, mode-matched means x̂_i and covariances P_i, and a row-stochastic
transition matrix Π (Π_ij = P(mode j now | mode i before), one per IMM or one for all):

    c_j     = Σ_i Π_ij μ_i                        predicted mode probabilities
    μ_{i|j} = Π_ij μ_i / c_j                      mixing probabilities
    x̂⁰_j    = Σ_i μ_{i|j} x̂_i                     mixed mean of mode j
    P⁰_j    = Σ_i μ_{i|j} [P_i + (x̂_i − x̂⁰_j)(x̂_i − x̂⁰_j)ᵀ]   mixed covariance

([Dikić] prints x_i⁰ in the spread term; it is x̂⁰_j.) Mode j's filter then predicts from
(x̂⁰_j, P⁰_j); the predicted mode probabilities c_j weigh the modes' likelihoods in the
update (eq. 18-19) and stand as the mode probabilities of an IMM that gets no plot.

The sums run in a common state layout: the modes' own layout when they all share one,
else the Singer layout [x, vx, ax, y, vy, ay(, z, vz, az)] with the conversions of
[Dikić] eq. 22 (:mod:`fusion.models.conversions`: CV gets zero acceleration, the
coordinated turn's (ψ, ω, v) map to velocities and accelerations, with their Jacobians).
The moments of every target mode j are one call of
:func:`fusion.filters.moment_matching.moment_match_rows_each` (compiled loops). Units are
the models' (m, m/s, m/s², rad, rad/s); the layout is the system frame's.
"""

from __future__ import annotations

import numpy as np

from ..models.conversions import from_common, to_common
from .moment_matching import moment_match_rows_each


def same_layout(models: list) -> bool:
    """True when every mode model has the same state layout (no conversion needed)."""
    return len({tuple(m.labels) for m in models}) == 1


def mixing_probabilities(mu: np.ndarray, Pi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """c (n, r) = Σ_i Π_ij μ_i and μ_{i|j} (n, r, r) [i, j] = Π_ij μ_i / c_j (eq. 15-16)
    for mode probabilities mu (n, r) and transition matrices Pi (n, r, r) or (r, r).
    A mode no IMM can reach (c_j = 0) gets weights 0 (its mixed moments are then the
    unweighted ones, see :func:`interact`)."""
    Pi = np.broadcast_to(Pi, (len(mu), *np.shape(Pi)[-2:]))
    c = np.einsum("ci,cij->cj", mu, Pi)
    w = mu[:, :, None] * Pi / np.maximum(c[:, None, :], 1e-300)
    return c, w


def interact(
    mu: np.ndarray, Pi: np.ndarray, xs: list[np.ndarray], Ps: list[np.ndarray], models: list
) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
    """Mixed initial conditions of every mode and the predicted mode probabilities.

    mu (n, r); Pi (n, r, r) or (r, r); xs[j] (n, d_j), Ps[j] (n, d_j, d_j) in mode j's
    layout; ``models`` the r mode models (their ``labels`` and the common-layout
    conversions). Returns (x⁰ list, P⁰ list, c (n, r)), each x⁰_j, P⁰_j in mode j's layout
    (eq. 15-17). One mode: (xs, Ps, c) unchanged."""
    r = len(models)
    if r == 1:
        c = np.einsum("ci,cij->cj", mu, np.broadcast_to(Pi, (len(mu), 1, 1)))
        return [xs[0]], [Ps[0]], c
    c, w = mixing_probabilities(mu, Pi)
    native = same_layout(models)
    pairs = [(x, P) if native else to_common(m, x, P) for m, x, P in zip(models, xs, Ps)]
    xc = np.stack([a for a, _ in pairs], axis=1)  # (n, r, dc)
    Pc = np.stack([b for _, b in pairs], axis=1)  # (n, r, dc, dc)
    xm, Pm = moment_match_rows_each(w, xc, Pc)  # every target mode j at once
    out = [
        (xm[:, j], Pm[:, j]) if native else from_common(m, xm[:, j], Pm[:, j])
        for j, m in enumerate(models)
    ]
    return [a for a, _ in out], [b for _, b in out], c
