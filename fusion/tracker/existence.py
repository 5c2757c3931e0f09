"""Target existence as a Markov chain ([thesis] §2.3, §3.2; (2.36), (3.40), (5.3), (5.18)).

The existence state of n tracks is held as an array ``(n, 2)`` of
``[p_detectable, p_undetectable]``: the probabilities that the target exists and can be
detected, and that it exists but cannot be (Markov chain two only; always 0 for Markov
chain one). Existence ψ is their sum; the probability of non-existence is the rest.

Association (IPDA, LM-IPDA, JIPDA) works with ψ_det = ``p_detectable``. It returns the
posterior ψ_det' and :func:`ExistenceChain.update` applies it: for MC1 ψ' = ψ_det'; for
MC2 (Musicki 1994 [LIT]) p_obs ← (1−δ)p_obs, p_unobs and p_non unchanged,
then normalised by 1−δ p_obs, where δ follows from ψ_det' = (1−δ)ψ_det/(1−δψ_det)
(2.41) as 1−δψ_det = (1−ψ_det)/(1−ψ_det').

Chain probabilities refer to a period ``T``; a prediction over dt uses the matrix power
Π^(dt/T) = V diag(λ^(dt/T)) V⁻¹ (eigendecomposition of Π) so that asynchronous batches
compose exactly. The prediction of n states is one compiled loop (numba, ``cache=True``):
per state the power Π^(dt/T) (entries clipped to [0, 1]) and the row-vector product
p Π^(dt/T), clipped to [0, 1] again.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def _predict_states(state, dt, lam, V, Vinv, period):
    """p Π^(dt/T) of n chain states (n, 2) (the third entry 1 − Σ), clipped to [0, 1]."""
    n = len(state)
    out = np.empty((n, 2))
    M = np.empty((3, 3))
    lam_t = np.empty(3)
    for k in range(n):
        t = max(dt[k], 0.0) / period
        for m in range(3):
            lam_t[m] = lam[m] ** t
        for i in range(3):
            for j in range(3):
                s = 0.0
                for m in range(3):
                    s += V[i, m] * lam_t[m] * Vinv[m, j]
                M[i, j] = min(max(s, 0.0), 1.0)
        p = (state[k, 0], state[k, 1], 1.0 - (state[k, 0] + state[k, 1]))
        for j in range(2):
            s = p[0] * M[0, j] + p[1] * M[1, j] + p[2] * M[2, j]
            out[k, j] = min(max(s, 0.0), 1.0)
    return out


@numba.njit(cache=True, nogil=True)
def _bound(state, dt, lam1, psi_inf, period):
    """ψ∞ + (ψ₀ − ψ∞) λ^(dt/T) of one state (2,) (:meth:`ExistenceChain.existence_bound`)."""
    psi0 = min(max(state[0] + state[1], 0.0), 1.0)
    return psi_inf + (psi0 - psi_inf) * lam1 ** (max(dt, 0.0) / period)


@numba.njit(cache=True, nogil=True)
def _bounds(state, dt, lam1, psi_inf, period):
    out = np.empty(len(state))
    for k in range(len(state)):
        out[k] = _bound(state[k], dt[k], lam1, psi_inf, period)
    return out


@numba.njit(cache=True, nogil=True)
def _screened(state, dt, lam, V, Vinv, period, lumped, level, also):
    """ψ (n,) of the states predicted over dt where the closed form ψ∞ + (ψ₀ − ψ∞) λ^(dt/T)
    (``lumped`` = (λ, ψ∞), λ ≤ 0: none) is below ``level`` or ``also``: the exact
    prediction (:func:`_predict_states`); 1 elsewhere."""
    n = len(state)
    out = np.ones(n)
    lam1, psi_inf = lumped
    one = np.empty((1, 2))
    t1 = np.empty(1)
    for k in range(n):
        if not also[k] and lam1 > 0.0 and _bound(state[k], dt[k], lam1, psi_inf, period) >= level:
            continue
        one[0, 0], one[0, 1], t1[0] = state[k, 0], state[k, 1], dt[k]
        p = _predict_states(one, t1, lam, V, Vinv, period)
        out[k] = min(max(p[0, 0] + p[0, 1], 0.0), 1.0)
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")  # x/0 as in NumPy
def _updated(state_pred, psi_post):
    """[ψ_det', clip(p_unobs (1 − ψ_det')/(1 − p_obs))] per state (the scale 1 where
    1 − p_obs ≤ 1e-300)."""
    n = len(state_pred)
    out = np.empty((n, 2))
    for k in range(n):
        denom = 1.0 - state_pred[k, 0]
        scale = (1.0 - psi_post[k]) / denom if denom > 1e-300 else 1.0
        out[k, 0] = psi_post[k]
        out[k, 1] = min(max(state_pred[k, 1] * scale, 0.0), 1.0)
    return out


class ExistenceChain:
    """A Markov chain over {detectable, undetectable, non-existent} with period ``period`` s.

    ``MarkovChainOne`` and ``MarkovChainTwo`` build the transition matrix Π (rows: from,
    columns: to) and the prediction is p_{k|k−1} = Πᵀ p_{k−1|k−1} (row-vector p Π)."""

    def __init__(self, Pi: np.ndarray, period: float) -> None:
        Pi = np.asarray(Pi, dtype=np.float64)
        if Pi.shape != (3, 3) or not np.allclose(Pi.sum(axis=1), 1.0) or (Pi < 0).any():
            raise ValueError(f"transition matrix must be 3x3 row-stochastic, got {Pi!r}")
        if not period > 0:
            raise ValueError(f"period = {period}: must be > 0 s")
        self.Pi = Pi
        self.period = float(period)
        lam, V = np.linalg.eig(Pi)
        if np.abs(lam.imag).max() > 1e-12 or (lam.real < -1e-12).any():
            raise ValueError(
                f"transition matrix eigenvalues {lam}: must be real and non-negative so that "
                "fractional periods are defined"
            )
        self._lam = np.clip(lam.real, 0.0, None)
        self._V = V.real
        self._Vinv = np.linalg.inv(self._V)

    def _lumped(self) -> tuple[float, float] | None:
        """(λ, ψ∞) of the existence alone, or None. Existence is a two-state chain when
        both existing states die alike (MC1, MC2): ψ' = b + λ ψ per period with
        λ = s − b, s = 1 − Π[0, 2], b = Π[2, 0] + Π[2, 1], ψ∞ = b / (1 − λ); λ > 0 so that
        λ^(dt/T) is the fractional power of the eigendecomposition."""
        Pi = self.Pi
        s, b = 1.0 - Pi[0, 2], Pi[2, 0] + Pi[2, 1]
        lam = s - b
        if Pi[0, 2] != Pi[1, 2] or not 0.0 < lam < 1.0:
            return None
        return lam, b / (1.0 - lam)

    def predict(self, state: np.ndarray, dt: np.ndarray) -> np.ndarray:
        """Predict ``state`` (n, 2) over ``dt`` (n,) seconds (3.40, 5.3)."""
        state = np.ascontiguousarray(state, dtype=np.float64)
        dt = np.ascontiguousarray(dt, dtype=np.float64).reshape(len(state))
        return _predict_states(state, dt, self._lam, self._V, self._Vinv, self.period)

    def existence_bound(self, state: np.ndarray, dt: np.ndarray) -> np.ndarray | None:
        """ψ of ``state`` (n, 2) predicted over ``dt`` (n,) s in closed form,
        ψ(t) = ψ∞ + (ψ₀ − ψ∞) λ^(dt/T) (the two-state existence chain the three states lump
        into, 2.36 / 3.40), or None when Π does not lump. It equals
        ``existence(predict(state, dt))`` up to rounding; it serves to find the few tracks
        whose predicted existence can be near a threshold, for which the exact
        prediction is then made (termination)."""
        lumped = self._lumped()
        if lumped is None:
            return None
        lam, psi_inf = lumped
        c = np.ascontiguousarray
        return _bounds(c(state, dtype=np.float64), c(dt, dtype=np.float64).reshape(len(state)),
                       lam, psi_inf, self.period)  # fmt: skip

    def existence_below(
        self, state: np.ndarray, dt: np.ndarray, level: float, also: np.ndarray
    ) -> np.ndarray:
        """ψ (n,) of ``state`` (n, 2) predicted over ``dt`` (n,) s (``existence(predict(…))``)
        for the states whose closed-form ψ (:meth:`existence_bound`) is below ``level`` and
        those where ``also`` (n,); 1 for the others. One compiled pass: the termination test
        of every track, where the exact prediction is made only near the threshold."""
        lumped = self._lumped() or (0.0, 0.0)
        return _screened(
            np.ascontiguousarray(state, dtype=np.float64),
            np.ascontiguousarray(dt, dtype=np.float64),
            self._lam, self._V, self._Vinv, self.period, lumped, float(level),
            np.ascontiguousarray(also, dtype=bool),
        )  # fmt: skip

    @staticmethod
    def existence(state: np.ndarray) -> np.ndarray:
        """ψ = p_detectable + p_undetectable."""
        return np.clip(state[:, 0] + state[:, 1], 0.0, 1.0)

    @staticmethod
    def update(state_pred: np.ndarray, psi_det_post: np.ndarray) -> np.ndarray:
        """Apply the association's posterior ψ_det' (2.41 / 5.18 / 6.7) to the chain state:
        1 − δ p_obs = (1 − p_obs)/(1 − ψ_det') renormalises p_unobs (one compiled loop)."""
        c = np.ascontiguousarray
        return _updated(c(state_pred, dtype=np.float64), c(psi_det_post, dtype=np.float64))


def markov_chain_one(delta11: float, delta21: float, period: float = 1.0) -> ExistenceChain:
    """MC1: ψ_{k|k−1} = Δ11 ψ + Δ21 (1 − ψ) per period (2.36 corrected, 3.40)."""
    Pi = np.array(
        [
            [delta11, 0.0, 1.0 - delta11],
            [delta11, 0.0, 1.0 - delta11],  # unused state: maps like 'detectable'
            [delta21, 0.0, 1.0 - delta21],
        ]
    )
    return ExistenceChain(Pi, period)


def markov_chain_two(
    delta11: float,
    delta21: float,
    obs_to_unobs: float,
    unobs_to_obs: float,
    period: float = 1.0,
) -> ExistenceChain:
    """MC2 (Musicki 1994 [LIT]): a target that survives (Δ11) stays or becomes detectable
    with the given per-period switching probabilities; a born target (Δ21) is detectable."""
    a, b = obs_to_unobs, unobs_to_obs
    Pi = np.array(
        [
            [delta11 * (1 - a), delta11 * a, 1.0 - delta11],
            [delta11 * b, delta11 * (1 - b), 1.0 - delta11],
            [delta21, 0.0, 1.0 - delta21],
        ]
    )
    return ExistenceChain(Pi, period)
