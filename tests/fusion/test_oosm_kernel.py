"""The compiled A1 noise terms and the per-matrix Cholesky test against NumPy's LAPACK
(inverse, solve, eigenvalues) on random states: well-posed priors, priors that are not
positive definite or not finite, and mixture posteriors that fail the PSD test."""

import numpy as np
import pytest
from skyfuse.fusion.filters.cholesky_kernels import positive_definite
from skyfuse.fusion.tracker.oosm import noise_terms


def _reference(x, P, Q, xp, Pp, known):
    """Bar-Shalom A1 (O1-O2) in the prior/posterior form with LAPACK, row by row."""
    Pxv, Pvv, corr = np.zeros_like(P), Q.copy(), np.zeros_like(x)
    for r in np.flatnonzero(known):
        if not (np.isfinite(Pp[r]).all() and np.isfinite(P[r]).all()):
            continue
        if np.linalg.eigvalsh(0.5 * (Pp[r] + Pp[r].T)).min() <= 0:
            continue
        if np.linalg.eigvalsh(0.5 * (P[r] + P[r].T)).min() <= 0:
            continue
        QPi = Q[r] @ np.linalg.inv(Pp[r])
        a_xv = P[r] @ np.linalg.inv(Pp[r]) @ Q[r]
        a_vv = Q[r] - QPi @ (Pp[r] - P[r]) @ QPi.T
        a_vv = 0.5 * (a_vv + a_vv.T)
        cond = a_vv - a_xv.T @ np.linalg.solve(P[r], a_xv)
        tol = 1e-6 * max(np.abs(np.diag(Q[r])).max(), 1e-300)
        if np.linalg.eigvalsh(0.5 * (cond + cond.T)).min() < -tol:
            continue
        Pxv[r], Pvv[r], corr[r] = a_xv, a_vv, QPi @ (x[r] - xp[r])
    return Pxv, Pvv, corr


def _spd(rng, n, d, scale=1.0):
    A = rng.normal(size=(n, d, d)) * scale
    return A @ np.swapaxes(A, 1, 2) + 0.1 * np.eye(d)


@pytest.mark.parametrize("d", [4, 5, 7, 9])
def test_a1_noise_terms_match_lapack(d):
    rng = np.random.default_rng(d)
    n = 300
    Q = _spd(rng, n, d, 0.3)
    P = _spd(rng, n, d)
    Pp = P + _spd(rng, n, d, 0.5)  # a Kalman-like prior: larger than the posterior
    Pp[::7] = _spd(rng, len(Pp[::7]), d, 0.2)  # mixture posteriors: PSD test fails
    Pp[3] = 0.0  # singular prior
    Pp[5, 1, 1] = np.nan
    P[11, 0, 0] = -1.0  # posterior not positive definite
    x, xp = rng.normal(size=(n, d)), rng.normal(size=(n, d))
    known = rng.random(n) < 0.9
    got = noise_terms(x, P, Q, xp, Pp, known)
    ref = _reference(x, P, Q, xp, Pp, known)
    fallback = np.all(got[0] == 0.0, axis=(1, 2))
    assert np.array_equal(fallback, np.all(ref[0] == 0.0, axis=(1, 2)))
    assert fallback[~known].all() and fallback[[3, 5, 11]].all()
    assert 0.05 < fallback[known].mean() < 0.5  # both outcomes are exercised
    for a, b in zip(got, ref):
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-10 * np.abs(b).max())


def test_positive_definite_matches_eigenvalues_and_flags_non_finite():
    rng = np.random.default_rng(3)
    for d in (1, 2, 3, 5, 8):
        B = rng.normal(size=(400, d, d))
        A = B @ np.swapaxes(B, 1, 2) / d + rng.uniform(-1.0, 0.5, size=(400, 1, 1)) * np.eye(d)
        A[:, 0, d - 1] += 1e-9  # slightly asymmetric: tested as (A + Aᵀ)/2
        A[0, 0, d - 1] = np.nan
        A[1, d - 1, 0] = np.inf
        ref = np.array(
            [np.isfinite(a).all() and np.linalg.eigvalsh(0.5 * (a + a.T)).min() > 0 for a in A]
        )
        assert 0 < ref.sum() < len(A)
        assert np.array_equal(positive_definite(A), ref)
    assert positive_definite(np.zeros((0, 3, 3))).shape == (0,)
