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

**Mixtures and IMM** (the densities' :class:`~.density.base.Retrodiction`): every Gaussian
component (every mode of every IMM component) is retrodicted with its own model and its
own posterior, with the track-level prior of the last step (moment-matched over the
components, per mode); the retrodicted components gate and weigh the late plots through
the density's own ``likelihoods`` (so p^τ_i is the OOSM likelihood N(z(τ); H x̂(τ|k),
S(τ)) / P_G), the association part and the existence update are the configured ones
(:mod:`.oosm_pass`).

The memory of the last step is one prior per track and mode: columns of the track store
(:mod:`.store`), declared by :class:`~.oosm_pass.OutOfSequence`.
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
