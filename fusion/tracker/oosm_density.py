"""The out-of-sequence update (:mod:`.oosm`, Bar-Shalom 2002 A1) over the components of
the track densities, vectorised over tracks × components (× modes):

* :class:`GaussianMixtureDensity` (IPDA / ITS with Singer memory, CV): every component
  c is retrodicted with the CV model from its own posterior (x̂^c, P^c) and the track's
  last prior; the late plots are gated and weighed by the density's ``likelihoods`` on
  the retrodicted components (p^c_i = N(z_i; H x̂^c(τ|k), S^c_i(τ)) / P_G); the children
  are the ITS ones of 5.12-5.15 with the Kalman update replaced by the OOSM update ((O5)
  of :mod:`.oosm`): the "no plot" child keeps x̂^c, P^c with weight β₀ ξ^c, the child of plot i
  is x̂^c(k|τ), P^c(k|τ) with weight β_i ξ^c p^c_i / p^τ_i; then the density's own
  Singer merge, pruning and estimate (``store_children``). The late plot enters the plot
  history as one more scan.
* :class:`IMMMixtureDensity`: the same per mode j, each mode retrodicted with its own
  model (CV, coordinated turn with the backward flow and its Jacobian, Singer), with the
  track's last prior of that mode. **Approximation**: no mode interaction over the lag
  (Π(−Δ) is not defined, and Π(Δ) over Δ ≤ max_lateness is close to I for the
  configured 0.95/0.05-per-period chains); the mode probabilities of a plot child are
  updated with the retrodicted likelihoods, μ^c_j ∝ μ^c_j N_j(z(τ)) (eq. 19 with μ in
  place of c), those of the no-plot child are left unchanged. Exact for one CV mode.

Particle densities have no OOSM here: their late plots are applied at the track's current
time as before (``Tracker`` counts them as ``oosm_unsupported``).
"""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.filters.moment_matching import moment_match

from .components import Mixture
from .density.gaussian_mixture import GaussianMixtureDensity, MixturePrediction, MixtureTable
from .density.imm_mixture import IMMComponents, IMMMixtureDensity, IMMPrediction, IMMTable
from .its import shift_history
from .oosm import oosm_update, retrodict


def supported(density) -> bool:
    return isinstance(density, (GaussianMixtureDensity, IMMMixtureDensity))


def mode_dims(density) -> list[int]:
    if isinstance(density, IMMMixtureDensity):
        return [m.dim for m in density.models]
    return [density.dim]


def track_priors(pred) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Track-level predicted state per mode of a density's Prediction (the last step's
    prior, :class:`~.oosm.LastStep`): moment match over the components with ξ^c (ξ^c c_j
    for IMM mode j)."""
    n = len(pred.rows)
    if isinstance(pred, IMMPrediction):
        comp = pred.comp
        out = [
            moment_match(comp.w * comp.mu[:, j], comp.x[j], comp.P[j], pred.loc, n)[1:]
            for j in range(len(comp.x))
        ]
        return [a for a, _ in out], [b for _, b in out]
    _, x, P = moment_match(pred.mix.w, pred.mix.x, pred.mix.P, pred.loc, n)
    return [x], [P]


def _take_rows(slots, rows: np.ndarray, n: int):
    inside = np.zeros(n, bool)
    inside[rows] = True
    cur = slots.tracks(inside)
    return cur, np.searchsorted(rows, cur.track)


def _prior_rows(priors, loc: np.ndarray, j: int):
    known, xs, Ps = priors
    if xs is None:
        return None, None, np.zeros(len(loc), bool)
    return xs[j][loc], Ps[j][loc], known[loc]


def retrodict_density(density, rows: np.ndarray, lag: np.ndarray, priors):
    """(prediction of the retrodicted components for ``likelihoods``, the current
    components, the cross terms C per mode) of tracks ``rows`` (sorted) over ``lag``
    (len(rows),) s; ``priors``: :meth:`LastStep.lookup` of the rows."""
    if isinstance(density, IMMMixtureDensity):
        cur, loc = _take_rows(density.slots, rows, len(density))
        xs, Ps, Cs = [], [], []
        for j, model in enumerate(density.models):
            xp, Pp, known = _prior_rows(priors, loc, j)
            x, P, C = retrodict(model, cur.x[j], cur.P[j], lag[loc], xp, Pp, known)
            xs.append(x)
            Ps.append(P)
            Cs.append(C)
        retro = IMMComponents(cur.track, cur.w, cur.hist, cur.mu, xs, Ps)
        pos = density.pos
        y = np.stack([xs[j][:, pos[j]] for j in range(len(xs))], axis=1)
        HPH = np.stack([Ps[j][:, pos[j]][:, :, pos[j]] for j in range(len(xs))], axis=1)
        return IMMPrediction(rows, retro, loc, y, HPH), cur, Cs
    cur, loc = _take_rows(density.slots, rows, len(density))
    xp, Pp, known = _prior_rows(priors, loc, 0)
    x, P, C = retrodict(density.model, cur.x, cur.P, lag[loc], xp, Pp, known)
    retro = Mixture(cur.track, cur.w, x, P, cur.hist)
    pos = density.pos
    pred = MixturePrediction(rows, cur.w, loc, x[:, pos], P[:, pos][:, :, pos], retro)
    return pred, cur, [C]


def oosm_children(density, pred, cur, Cs, table, beta0: np.ndarray, beta: np.ndarray):
    """The updated components (before merging) of the retrodicted tracks: the current
    components with β₀ (no plot) and one OOSM-updated child per gated (component, plot)."""
    if isinstance(density, IMMMixtureDensity):
        return _imm_children(density, pred, cur, Cs, table, beta0, beta)
    return _gm_children(density, pred, cur, Cs[0], table, beta0, beta)


def _gm_children(
    density, pred: MixturePrediction, cur: Mixture, C, t: MixtureTable, beta0, beta
) -> Mixture:
    hist0 = shift_history(cur.hist, np.zeros(len(cur), np.int64))
    null = Mixture(cur.track, cur.w * beta0[pred.loc], cur.x, cur.P, hist0)
    pairs = t.pairs
    if len(pairs) == 0:
        return null
    c = pairs.state
    w = cur.w[c] * beta[t.pair_row] * t.p_pair / t.p[t.pair_row]
    x, P = oosm_update(cur.x[c], cur.P[c], C[c], density.H, pairs.nu, pairs.S)
    hist = shift_history(cur.hist[c], t.uid[pairs.plot])
    children = Mixture.concat([null, Mixture(cur.track[c], w, x, P, hist)])
    return children.take(np.flatnonzero(children.w > 0.0))


def _imm_children(
    density, pred: IMMPrediction, cur: IMMComponents, Cs, t: IMMTable, beta0, beta
) -> IMMComponents:
    hist0 = shift_history(cur.hist, np.zeros(len(cur), np.int64))
    null = IMMComponents(cur.track, cur.w * beta0[pred.loc], hist0, cur.mu, cur.x, cur.P)
    if len(t.pair_comp) == 0:
        return null
    c, p = t.pair_comp, t.pair_plot
    w = cur.w[c] * beta[t.pair_row] * t.p_pair / t.p[t.pair_row]
    lw = t.log_n + np.log(np.maximum(cur.mu[c], 1e-300))
    mu = np.exp(lw - lw.max(axis=1, keepdims=True))
    mu /= mu.sum(axis=1, keepdims=True)
    xs, Ps = [], []
    for j in range(len(cur.x)):
        x, P = oosm_update(cur.x[j][c], cur.P[j][c], Cs[j][c], density.H[j], t.nu[:, j], t.S[:, j])
        xs.append(x)
        Ps.append(P)
    upd = IMMComponents(cur.track[c], w, shift_history(cur.hist[c], t.uid[p]), mu, xs, Ps)
    return IMMComponents.concat([null, upd])
