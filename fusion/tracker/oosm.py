"""Out-of-sequence measurement (OOSM) update: a plot older than a track's current time
updates the track's *current* state, through the retrodiction of the track to the plot
time (Y. Bar-Shalom, "Update with out-of-sequence measurements in tracking: exact
solution", IEEE TAES 38(3), 2002, algorithm A1, referred to as [BS02]; the steps below
are numbered (O1)-(O5) here).

Notation (system frame, metres and m/s; times in seconds): the track was last updated at
t_k with the prior x̂(k|k−1), P(k|k−1) and posterior x̂(k|k), P(k|k); a plot z(τ) with
covariance R(τ) and t_{k−1} ≤ τ < t_k arrives late. Δ = t_k − τ > 0 (the *lag*), F(τ, k)
the backward transition (F(Δ)⁻¹ of a linear model; the Jacobian of f(·, −Δ) of a
nonlinear one, with the backward flow f(·, −Δ) for the mean) and Q(k, τ) = Q(Δ) the
process noise covariance over [τ, t_k].

A1 needs the last step's innovation ν(k), its covariance S(k) and P(k|k−1). They are
written here in terms of the last prior and posterior only, by the Kalman identities
K ν = x̂(k|k) − x̂(k|k−1), Hᵀ S⁻¹ = P⁻¹(k|k−1) K and I − K H = P(k|k) P⁻¹(k|k−1):

* (O1) retrodicted state:
  x̂(τ|k) = F(τ, k) [x̂(k|k) − Q P⁻¹(k|k−1) (x̂(k|k) − x̂(k|k−1))];
* (O2) noise covariances given Z^k: P_vv = Q − Q Hᵀ S⁻¹ H Q
  = Q − Q P⁻¹(k|k−1) (P(k|k−1) − P(k|k)) P⁻¹(k|k−1) Q,
  P_xv = Q − P(k|k−1) Hᵀ S⁻¹ H Q = P(k|k) P⁻¹(k|k−1) Q;
* (O3) retrodicted covariance: P(τ|k) = F(τ,k) [P(k|k) + P_vv − P_xv − P_xvᵀ] F(τ,k)ᵀ;
* (O4) cross covariance: P_xz = [P(k|k) − P_xv] F(τ, k)ᵀ H(τ)ᵀ;
* (O5) OOSM update: S(τ) = H P(τ|k) Hᵀ + R(τ), W = P_xz S(τ)⁻¹,
  x̂(k|τ) = x̂(k|k) + W (z(τ) − H x̂(τ|k)),  P(k|τ) = P(k|k) − W S(τ) Wᵀ.

For one Kalman filter and one-step lag (τ after the previous update) this is exact: the
posterior equals the one of processing the plots in time order (tested). Beyond one step
(the plot older than the last two updates) the same equations use the last step's
information only, an approximation: the exact multi-lag solution (Bar-Shalom, Chen and
Mallick, "One-step solution for the multistep out-of-sequence-measurement problem in
tracking", IEEE TAES 40(1), 2004, algorithm Al1) needs the information accumulated since
τ, which is not stored. Monte Carlo NEES two steps behind stays consistent (tested).

**Without a stored last step** (a new or resumed track, or a density without the
memory), the track's posterior is retrodicted with the process noise taken independent
of it (P_xv = 0, P_vv = Q, no ν term): P(τ|k) = F (P(k|k) + Q) Fᵀ, P_xz = P(k|k) Fᵀ Hᵀ.
That joint Gaussian of (x(k), z(τ)) is positive semi-definite by construction, and the
same fallback is used for any component whose A1 conditional noise covariance
P_vv − P_xvᵀ P⁻¹(k|k) P_xv is not positive semi-definite (a mixture posterior that is not
a Kalman posterior of the stored prior), so every OOSM posterior is a valid covariance.

**Mixtures and IMM** (:mod:`.oosm_density`): every Gaussian component (every mode of
every IMM component) is retrodicted with its own model and its own posterior, with the
track-level prior of the last step (moment-matched over the components, per mode); the
retrodicted components gate and weigh the late plots through the density's own
``likelihoods`` (so p^τ_i is the OOSM likelihood N(z(τ); H x̂(τ|k), S(τ)) / P_G), the
association part and the existence update are the configured ones (:mod:`.oosm_pass`).

The memory of the last step (:class:`LastStep`) is one prior per track and mode, keyed by
track id, bounded by the number of live tracks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NS = 1e-9


def backward(model, x: np.ndarray, lag: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(f(x, −Δ) (n, d), F(τ, k) (n, d, d), Q(Δ) (n, d, d)) of n states x over lags
    ``lag`` (n,) s > 0: the backward flow of a nonlinear model (``model.transition`` with
    −Δ, Jacobian at x) or F(Δ)⁻¹ x of a linear one (the inverse of the forward transition,
    so no model needs to accept negative intervals); Q(Δ) = the forward noise over the
    lag."""
    lag = np.asarray(lag, dtype=np.float64)
    if getattr(model, "nonlinear", False):
        xb, Fb = model.transition(x, -lag)
        return xb, Fb, model.Q(lag, x)
    Fb = np.linalg.inv(model.F(lag))
    return np.einsum("nij,nj->ni", Fb, x), Fb, model.Q(lag)


def _positive_definite(A: np.ndarray) -> np.ndarray:
    """(n,) whether each symmetric (n, d, d) matrix is finite and positive definite."""
    ok = np.isfinite(A).all(axis=(1, 2))
    out = np.zeros(len(A), bool)
    if ok.any():
        out[ok] = np.linalg.eigvalsh(_sym(A[ok])).min(axis=1) > 0.0
    return out


def _sym(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + np.swapaxes(A, -1, -2))


def _tr(A: np.ndarray) -> np.ndarray:
    return np.swapaxes(A, -1, -2)


def noise_terms(
    x: np.ndarray,
    P: np.ndarray,
    Q: np.ndarray,
    x_prior: np.ndarray,
    P_prior: np.ndarray,
    known: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(P_xv, P_vv, Q P⁻¹(k|k−1) (x̂(k|k) − x̂(k|k−1))) per state (O1-O2 in the
    prior/posterior form of the module docstring); the independent-noise fallback
    (0, Q, 0) where ``known`` is False or the A1 conditional noise covariance is not PSD."""
    Pxv = np.zeros_like(P)
    Pvv = Q.copy()
    corr = np.zeros_like(x)
    rows = np.flatnonzero(known)
    if len(rows):  # A1 needs P(k|k−1) and P(k|k) positive definite (and finite)
        rows = rows[_positive_definite(P_prior[rows]) & _positive_definite(P[rows])]
    if len(rows):
        Pp_inv = np.linalg.inv(P_prior[rows])
        Qr = Q[rows]
        QPi = Qr @ Pp_inv
        a_xv = P[rows] @ Pp_inv @ Qr
        a_vv = _sym(Qr - QPi @ (P_prior[rows] - P[rows]) @ _tr(QPi))
        cond = a_vv - _tr(a_xv) @ np.linalg.solve(P[rows], a_xv)
        scale = np.maximum(np.abs(np.diagonal(Qr, axis1=1, axis2=2)).max(axis=1), 1e-300)
        ok = np.linalg.eigvalsh(_sym(cond)).min(axis=1) >= -1e-6 * scale
        good = rows[ok]
        Pxv[good], Pvv[good] = a_xv[ok], a_vv[ok]
        corr[good] = np.einsum("nij,nj->ni", QPi[ok], x[good] - x_prior[good])
    return Pxv, Pvv, corr


def retrodict(
    model,
    x: np.ndarray,
    P: np.ndarray,
    lag: np.ndarray,
    x_prior: np.ndarray | None = None,
    P_prior: np.ndarray | None = None,
    known: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Retrodiction of n posteriors x (n, d), P (n, d, d) at t_k over ``lag`` (n,) s:
    (x̂(τ|k) (n, d), P(τ|k) (n, d, d), C = [P(k|k) − P_xv] F(τ, k)ᵀ (n, d, d)), so that
    P_xz = C Hᵀ (O1-O4). ``x_prior``, ``P_prior`` (n, d(, d)): the last step's
    prior, used where ``known`` (n,) is True (default: everywhere it is given)."""
    n = len(x)
    if x_prior is None or P_prior is None:
        x_prior, P_prior = x, P
        known = np.zeros(n, bool)
    elif known is None:
        known = np.ones(n, bool)
    _, _, Q = backward(model, x, lag)
    Pxv, Pvv, corr = noise_terms(x, P, Q, x_prior, P_prior, known)
    x_tau, Fb, _ = backward(model, x - corr, lag)
    M = P + Pvv - Pxv - _tr(Pxv)
    P_tau = _sym(Fb @ M @ _tr(Fb))
    C = (P - Pxv) @ _tr(Fb)
    return x_tau, P_tau, C


def oosm_update(
    x: np.ndarray, P: np.ndarray, C: np.ndarray, H: np.ndarray, nu: np.ndarray, S: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """x̂(k|τ), P(k|τ) (O5) of n current states x (n, d), P (n, d, d) with
    cross terms C (n, d, d) (:func:`retrodict`), measurement matrix H (k, d), late-plot
    innovations ν = z(τ) − H x̂(τ|k) (n, k) and their covariances S(τ) (n, k, k)."""
    Pxz = C @ H.T
    W = _tr(np.linalg.solve(S, _tr(Pxz)))
    x_new = x + np.einsum("nij,nj->ni", W, nu)
    return x_new, _sym(P - W @ _tr(Pxz))


@dataclass
class LastStep:
    """The prior of every track's last update, per mode (one mode for a Gaussian
    mixture): ids (n,) sorted, t (n,) ns the update time, x[j] (n, d_j), P[j] (n, d_j,
    d_j) the track-level predicted state of mode j at t (moment-matched over the
    track's components with weights ξ^c μ^c_j)."""

    ids: np.ndarray
    t: np.ndarray
    x: list[np.ndarray]
    P: list[np.ndarray]

    @classmethod
    def empty(cls, dims: list[int]) -> LastStep:
        return cls(
            np.zeros(0, np.int64),
            np.zeros(0, np.int64),
            [np.zeros((0, d)) for d in dims],
            [np.zeros((0, d, d)) for d in dims],
        )

    def __len__(self) -> int:
        return len(self.ids)

    def record(self, ids: np.ndarray, t: np.ndarray, x: list, P: list, live: np.ndarray) -> None:
        """Store the priors of tracks ``ids`` (unique) updated at ``t``: in place for the
        ids stored, appended (in id order) for the others; the ids no longer ``live``
        (the tracker's ids) are forgotten once the store exceeds 2 × live + 64 entries,
        so it stays bounded by the tracks."""
        ids = np.asarray(ids, dtype=np.int64)
        t = np.asarray(t, dtype=np.int64)
        pos = np.minimum(np.searchsorted(self.ids, ids), max(len(self.ids) - 1, 0))
        have = (self.ids[pos] == ids) if len(self.ids) else np.zeros(len(ids), bool)
        p = pos[have]
        self.t[p] = t[have]
        for j in range(len(self.x)):
            self.x[j][p], self.P[j][p] = x[j][have], P[j][have]
        if (~have).any():
            new = ~have
            self._merge(ids[new], t[new], [a[new] for a in x], [a[new] for a in P])
        if len(self.ids) > 2 * len(live) + 64:
            keep = np.isin(self.ids, live)
            self.ids, self.t = self.ids[keep], self.t[keep]
            self.x = [a[keep] for a in self.x]
            self.P = [a[keep] for a in self.P]

    def _merge(self, ids: np.ndarray, t: np.ndarray, x: list, P: list) -> None:
        all_ids = np.concatenate([self.ids, ids])
        order = np.argsort(all_ids, kind="stable")
        self.ids = all_ids[order]
        self.t = np.concatenate([self.t, t])[order]
        self.x = [np.concatenate([a, b])[order] for a, b in zip(self.x, x)]
        self.P = [np.concatenate([a, b])[order] for a, b in zip(self.P, P)]

    def lookup(self, ids: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, list, list]:
        """(known (s,), x[j] (s, d_j), P[j]) of tracks ``ids`` whose stored step is the
        one at their current time ``t`` (else known False and the rows are placeholders)."""
        ids = np.asarray(ids, dtype=np.int64)
        if len(self.ids) == 0:
            return np.zeros(len(ids), bool), None, None
        pos = np.minimum(np.searchsorted(self.ids, ids), len(self.ids) - 1)
        known = (self.ids[pos] == ids) & (self.t[pos] == np.asarray(t, dtype=np.int64))
        return known, [a[pos] for a in self.x], [a[pos] for a in self.P]
