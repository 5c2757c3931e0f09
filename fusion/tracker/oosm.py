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

import numpy as np

from .oosm_kernel import a1_terms_into

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
    (0, Q, 0) where ``known`` is False, where P(k|k−1) or P(k|k) is not positive definite
    (or not finite), or where the A1 conditional noise covariance is not PSD
    (:mod:`.oosm_kernel`)."""
    f8 = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
    Q = f8(Q)
    Pxv = np.zeros(P.shape)
    Pvv = Q.copy()
    corr = np.zeros(x.shape)
    rows = np.flatnonzero(known)
    if len(rows):
        a1_terms_into(f8(x), f8(P), Q, f8(x_prior), f8(P_prior), rows, Pxv, Pvv, corr)
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


class LastStep:
    """The prior of every track's last update, per mode (one mode for a Gaussian
    mixture), keyed by track id: slot s holds ids[s], t[s] ns the update time, x[j][s]
    (d_j,) and P[j][s] (d_j, d_j) the track-level predicted state of mode j at t
    (moment-matched over the track's components with weights ξ^c μ^c_j). Slots
    0 … len − 1 are used, in the order the tracks were first stored; ``keys`` are their ids
    sorted and ``order`` the slot of each key, so a new track is a write into the next
    free slot (the arrays grow by doubling) and never a copy of the stored states."""

    def __init__(self, dims: list[int], capacity: int = 64) -> None:
        self.n = 0
        self.ids = np.zeros(capacity, np.int64)
        self.t = np.zeros(capacity, np.int64)
        self.x = [np.zeros((capacity, d)) for d in dims]
        self.P = [np.zeros((capacity, d, d)) for d in dims]
        self.keys = np.zeros(0, np.int64)
        self.order = np.zeros(0, np.int64)

    @classmethod
    def empty(cls, dims: list[int]) -> LastStep:
        return cls(dims)

    def __len__(self) -> int:
        return self.n

    def _slots(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(stored (m,), slot (m,)) of track ids (m,); slot is a placeholder (0) where
        not stored."""
        if self.n == 0:
            return np.zeros(len(ids), bool), np.zeros(len(ids), np.int64)
        pos = np.minimum(np.searchsorted(self.keys, ids), self.n - 1)
        return self.keys[pos] == ids, self.order[pos]

    def record(self, ids: np.ndarray, t: np.ndarray, x: list, P: list, live: np.ndarray) -> None:
        """Store the priors of tracks ``ids`` (unique) updated at ``t``: in place for the
        ids stored, in new slots for the others; the ids no longer ``live`` (the tracker's
        ids) are forgotten once the store exceeds 2 × live + 64 entries, so it stays
        bounded by the tracks."""
        ids = np.asarray(ids, dtype=np.int64)
        t = np.asarray(t, dtype=np.int64)
        have, slot = self._slots(ids)
        s = slot[have]
        self.t[s] = t[have]
        for j in range(len(self.x)):
            self.x[j][s], self.P[j][s] = x[j][have], P[j][have]
        if not have.all():
            new = ~have
            self._append(ids[new], t[new], [a[new] for a in x], [a[new] for a in P])
        if self.n > 2 * len(live) + 64:
            self._compact(np.isin(self.ids[: self.n], live))

    def _append(self, ids: np.ndarray, t: np.ndarray, x: list, P: list) -> None:
        lo, hi = self.n, self.n + len(ids)
        if hi > len(self.ids):
            self._resize(max(hi, 2 * len(self.ids)))
        self.ids[lo:hi], self.t[lo:hi] = ids, t
        for j in range(len(self.x)):
            self.x[j][lo:hi], self.P[j][lo:hi] = x[j], P[j]
        self.n = hi
        by_id = np.argsort(ids, kind="stable")
        new_keys, new_slots = ids[by_id], lo + by_id
        if not len(self.keys) or new_keys[0] > self.keys[-1]:  # new tracks: the largest ids
            self.keys = np.concatenate([self.keys, new_keys])
            self.order = np.concatenate([self.order, new_slots])
            return
        at = np.searchsorted(self.keys, new_keys)
        self.keys = np.insert(self.keys, at, new_keys)
        self.order = np.insert(self.order, at, new_slots)

    def _resize(self, capacity: int) -> None:
        def grow(a: np.ndarray) -> np.ndarray:
            b = np.zeros((capacity, *a.shape[1:]), a.dtype)
            b[: self.n] = a[: self.n]
            return b

        self.ids, self.t = grow(self.ids), grow(self.t)
        self.x, self.P = [grow(a) for a in self.x], [grow(a) for a in self.P]

    def _compact(self, keep: np.ndarray) -> None:
        """Keep the used slots where ``keep`` (n,), in their order."""
        idx = np.flatnonzero(keep)
        self.ids[: len(idx)], self.t[: len(idx)] = self.ids[idx], self.t[idx]
        for j in range(len(self.x)):
            self.x[j][: len(idx)], self.P[j][: len(idx)] = self.x[j][idx], self.P[j][idx]
        self.n = len(idx)
        self._index()

    def _index(self) -> None:
        self.order = np.argsort(self.ids[: self.n], kind="stable")
        self.keys = self.ids[self.order]

    def problem(self) -> str | None:
        """Why the store's arrays are inconsistent (a restored state), ``None`` if not."""
        cap = len(self.ids)
        sizes = [len(self.t), *map(len, self.x), *map(len, self.P)]
        if not 0 <= self.n <= cap or any(k != cap for k in sizes):
            return f"last-step store of {self.n} in {cap} slots, arrays of {sizes} rows"
        if len(self.keys) != self.n or len(self.order) != self.n:
            return f"last-step index of {len(self.keys)} keys for {self.n} slots"
        if self.n and not np.array_equal(self.ids[self.order], self.keys):
            return "last-step index does not match the stored ids"
        return None

    def lookup(self, ids: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, list, list]:
        """(known (s,), x[j] (s, d_j), P[j]) of tracks ``ids`` whose stored step is the
        one at their current time ``t`` (else known False and the rows are placeholders)."""
        ids = np.asarray(ids, dtype=np.int64)
        if self.n == 0:
            return np.zeros(len(ids), bool), None, None
        have, slot = self._slots(ids)
        known = have & (self.t[slot] == np.asarray(t, dtype=np.int64))
        return known, [a[slot] for a in self.x], [a[slot] for a in self.P]
