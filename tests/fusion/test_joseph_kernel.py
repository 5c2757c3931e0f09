"""The compiled Joseph-form covariance update and grouped moment matching against the
NumPy expressions they replace (random states, shared and per-state R, weightless and
absent groups)."""

import numpy as np
import pytest
from skyfuse.fusion.filters.kalman import joseph_covariance
from skyfuse.fusion.filters.moment_matching import moment_match


def _joseph_ref(P, K, H, R):
    A = np.eye(P.shape[-1]) - K @ H
    Pn = A @ P @ np.swapaxes(A, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
    return 0.5 * (Pn + np.swapaxes(Pn, -1, -2))


@pytest.mark.parametrize("d,k", [(4, 2), (5, 2), (7, 3), (6, 3)])
def test_joseph_matches_the_matrix_expression(d, k):
    rng = np.random.default_rng(d * 10 + k)
    n = 200
    A = rng.normal(size=(n, d, d))
    P = A @ np.swapaxes(A, 1, 2) * 1e2
    K = rng.normal(size=(n, d, k))
    H = np.eye(k, d)
    Rn = rng.normal(size=(n, k, k))
    Rn = Rn @ np.swapaxes(Rn, 1, 2) * 50
    for R in (Rn, Rn[0]):
        got, ref = joseph_covariance(P, K, H, R), _joseph_ref(P, K, H, R)
        np.testing.assert_allclose(got, ref, rtol=1e-11, atol=1e-9 * np.abs(ref).max())
        assert np.array_equal(got, np.swapaxes(got, 1, 2))  # exactly symmetric
    single = joseph_covariance(P[0], K[0], H, Rn[0])
    np.testing.assert_allclose(single, _joseph_ref(P[:1], K[:1], H, Rn[0])[0], rtol=1e-11)


@pytest.mark.parametrize("d,k", [(4, 2), (6, 3), (9, 3), (3, 1)])
def test_update_with_innovation_matches_the_textbook_update(d, k):
    """x + K ν and the Joseph P with K = P Hᵀ S⁻¹ by an explicit inverse, for a
    selection H (the tracker's) and a general one; S = H P Hᵀ + R."""
    from skyfuse.fusion.filters.kalman import update_with_innovation

    rng = np.random.default_rng(d * 7 + k)
    n = 100
    A = rng.normal(size=(n, d, d))
    P = A @ np.swapaxes(A, 1, 2) * 1e2 + np.eye(d)
    x, nu = rng.normal(size=(n, d)) * 1e3, rng.normal(size=(n, k)) * 30
    R = rng.normal(size=(n, k, k))
    R = R @ np.swapaxes(R, 1, 2) * 50 + np.eye(k)
    for H in (np.eye(k, d), rng.normal(size=(k, d))):
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        xn, Pn = update_with_innovation(x, P, H, S, nu, R)
        np.testing.assert_allclose(xn, x + np.einsum("nij,nj->ni", K, nu), rtol=1e-10)
        ref = _joseph_ref(P, K, H, R)
        np.testing.assert_allclose(Pn, ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())
    if k != 2:  # an S that is not positive definite: the factorisation fails
        with pytest.raises(ValueError):
            update_with_innovation(x[:1], P[:1], H, -S[:1], nu[:1], R[:1])


def _moments_ref(w, x, P, group, G):
    """Per group: W = Σ w, mean and spread by the formulas; equal weights in a
    weightless group; NaN for a group without components."""
    d = x.shape[1]
    W, xm, Pm = np.zeros(G), np.full((G, d), np.nan), np.full((G, d, d), np.nan)
    for g in range(G):
        m = group == g
        if not m.any():
            continue
        W[g] = w[m].sum()
        ww = w[m] if W[g] > 0 else np.ones(m.sum())
        xm[g] = (ww[:, None] * x[m]).sum(0) / ww.sum()
        dx = x[m] - xm[g]
        S = (ww[:, None, None] * (P[m] + dx[:, :, None] * dx[:, None, :])).sum(0) / ww.sum()
        Pm[g] = 0.5 * (S + S.T)
    return W, xm, Pm


def test_grouped_moment_matching_matches_the_formulas():
    rng = np.random.default_rng(8)
    for trial in range(100):
        C, d, G = int(rng.integers(1, 60)), int(rng.choice([4, 5, 7])), int(rng.integers(2, 20))
        group = rng.integers(0, G, C)
        w = rng.random(C) * (rng.random(C) > 0.2)
        w[group == group[0]] = 0.0 if trial % 5 == 0 else w[group == group[0]]
        x = rng.normal(size=(C, d)) * 1e3
        A = rng.normal(size=(C, d, d))
        P = A @ np.swapaxes(A, 1, 2)
        for got, ref in zip(moment_match(w, x, P, group, G), _moments_ref(w, x, P, group, G)):
            np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-9)
