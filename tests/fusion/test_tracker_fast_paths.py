"""The tracker's fast paths against independent references: closed-form 2x2 innovation
algebra (the gating's per-pair kernels, the gain) vs LAPACK, row/grouped moment matching
vs explicit loops, the closed-form existence prediction vs the chain recursion, CV layout
placement vs the selector matrix, and the one-pass plot validation vs hand-counted
rejections."""

import numpy as np
import pytest
from skyfuse.fusion.filters.moment_matching import moment_match, moment_match_rows
from skyfuse.fusion.filters.small_spd import largest_eigenvalue
from skyfuse.fusion.models import ConstantVelocity
from skyfuse.fusion.models.conversions import from_common, to_common
from skyfuse.fusion.tracker.existence import markov_chain_one, markov_chain_two
from skyfuse.fusion.tracker.measurements import MeasurementBatch


def _spd(rng, n, k):
    A = rng.normal(size=(n, k, k))
    return A @ A.transpose(0, 2, 1) + 0.5 * np.eye(k)


def _pair_statistics(S, nu):
    """d², ln det S of every pair by the gating's per-pair kernels (the closed form for
    k = 2, the Cholesky form otherwise)."""
    from skyfuse.fusion.association.gating_kernels import statistics_2x2, statistics_cholesky

    k = S.shape[-1]
    L, w = np.zeros((k, k)), np.empty(k)
    one = (lambda A, v: statistics_2x2(A, v)) if k == 2 else (
        lambda A, v: statistics_cholesky(np.ascontiguousarray(A), v, L, w)
    )  # fmt: skip
    return np.array([one(S[i], nu[i]) for i in range(len(S))]).T


@pytest.mark.parametrize("k", [2, 3])
def test_pair_statistics_against_inverse_and_slogdet(k):
    rng = np.random.default_rng(1)
    S, nu = _spd(rng, 50, k), rng.normal(size=(50, k))
    d2, logdet = _pair_statistics(S, nu)
    ref = np.einsum("ni,nij,nj->n", nu, np.linalg.inv(S), nu)
    np.testing.assert_allclose(d2, ref, rtol=1e-12)
    np.testing.assert_allclose(logdet, np.linalg.slogdet(S)[1], rtol=1e-12, atol=1e-12)


def test_quadratic_of_indefinite_2x2_is_outside_every_gate():
    S = np.array([[[1.0, 2.0], [2.0, 1.0]], [[-1.0, 0.0], [0.0, -1.0]]])
    d2, _ = _pair_statistics(S, np.ones((2, 2)))
    assert np.isinf(d2).all()


@pytest.mark.parametrize("k", [2, 3])
def test_gain_against_inverse(k):
    """K of the compiled update (x + K ν with ν = e_j gives column j of K)."""
    from skyfuse.fusion.filters.kalman import update_with_innovation

    rng = np.random.default_rng(2)
    S = _spd(rng, 20, k)
    P = _spd(rng, 20, 4)
    H = np.zeros((k, 4))
    H[np.arange(k), np.arange(k)] = 1.0
    ref = P @ H.T @ np.linalg.inv(S)
    for j in range(k):
        nu = np.zeros((20, k))
        nu[:, j] = 1.0
        x, _ = update_with_innovation(np.zeros((20, 4)), P, H, S, nu, np.eye(k))
        np.testing.assert_allclose(x, ref[:, :, j], rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("k", [1, 2, 3])
def test_largest_eigenvalue_against_lapack(k):
    rng = np.random.default_rng(3)
    C = _spd(rng, 40, k) * 1e4
    C[0] = np.eye(k) * 7.0  # equal eigenvalues
    np.testing.assert_allclose(largest_eigenvalue(C), np.linalg.eigvalsh(C)[:, -1], rtol=1e-12)


def _loop_match(w, x, P):
    W = w.sum()
    m = (w[:, None] * x).sum(axis=0) / W
    C = sum(wi * (Pi + np.outer(xi - m, xi - m)) for wi, xi, Pi in zip(w, x, P)) / W
    return W, m, C


def test_moment_match_rows_against_a_loop():
    rng = np.random.default_rng(3)
    w = rng.uniform(size=(7, 3))
    w /= w.sum(axis=1, keepdims=True)
    x, P = rng.normal(size=(7, 3, 4)), _spd(rng, 21, 4).reshape(7, 3, 4, 4)
    xm, Pm = moment_match_rows(w, x, P)
    for n in range(7):
        _, m, C = _loop_match(w[n], x[n], P[n])
        np.testing.assert_allclose(xm[n], m, rtol=1e-12)
        np.testing.assert_allclose(Pm[n], C, rtol=1e-12)


def test_moment_match_unsorted_groups_against_a_loop():
    rng = np.random.default_rng(4)
    group = np.array([2, 0, 2, 1, 0, 2, 4])  # group 3 empty, unsorted
    w = rng.uniform(size=7)
    x, P = rng.normal(size=(7, 3)), _spd(rng, 7, 3)
    with np.errstate(invalid="ignore"):  # the empty group: 0 / 0
        W, xm, Pm = moment_match(w, x, P, group, 5)
    for g in (0, 1, 2, 4):
        sel = group == g
        Wg, m, C = _loop_match(w[sel], x[sel], P[sel])
        assert W[g] == pytest.approx(Wg)
        np.testing.assert_allclose(xm[g], m, rtol=1e-12)
        np.testing.assert_allclose(Pm[g], C, rtol=1e-12)
    assert W[3] == 0.0 and np.isnan(xm[3]).all()


@pytest.mark.parametrize(
    "chain, d11, d21",
    [
        (markov_chain_one(0.98, 0.01, 1.0), 0.98, 0.01),
        (markov_chain_two(0.97, 0.0, 0.1, 0.3, 1.0), 0.97, 0.0),
    ],
)
def test_existence_bound_against_the_recursion(chain, d11, d21):
    """Integer dt: ψ_k = Δ11 ψ_{k−1} + Δ21 (1 − ψ_{k−1}) per period (2.36, 3.40)."""
    rng = np.random.default_rng(5)
    state = rng.uniform(0.0, 0.5, (30, 2))
    steps = rng.integers(0, 12, 30)
    psi = state.sum(axis=1)
    ref = psi.copy()
    for i, k in enumerate(steps):
        for _ in range(k):
            ref[i] = d11 * ref[i] + d21 * (1.0 - ref[i])
    np.testing.assert_allclose(chain.existence_bound(state, steps.astype(float)), ref, atol=1e-13)


def test_cv_common_layout_against_the_selector_matrix():
    rng = np.random.default_rng(6)
    for ndim in (2, 3):
        cv = ConstantVelocity(ndim=ndim)
        Sel = np.zeros((3 * ndim, 2 * ndim))
        for a in range(ndim):
            Sel[3 * a, 2 * a] = Sel[3 * a + 1, 2 * a + 1] = 1.0
        x, P = rng.normal(size=(5, 2 * ndim)), _spd(rng, 5, 2 * ndim)
        xc, Pc = to_common(cv, x, P)
        np.testing.assert_array_equal(xc, x @ Sel.T)
        np.testing.assert_allclose(Pc, Sel @ P @ Sel.T, rtol=0, atol=1e-15)
        xb, Pb = from_common(cv, xc + 1.0, Pc + 1.0)
        np.testing.assert_array_equal(xb, (xc + 1.0) @ Sel)
        np.testing.assert_allclose(Pb, Sel.T @ (Pc + 1.0) @ Sel, rtol=0, atol=1e-12)


def _batch(z, R):
    return MeasurementBatch(0, "r", z, R, 0.9, 1e-9)


def test_validation_clean_empty_and_bad_batches():
    R = np.array([[100.0, 5.0], [5.0, 100.0]])
    z = np.arange(10.0).reshape(5, 2)
    clean = _batch(z, R).validated(2)
    assert len(clean) == 5 and clean.rejected == {}
    np.testing.assert_array_equal(clean.z, z)
    assert clean.R.shape == (5, 2, 2) and clean.clutter_density.shape == (5,)
    assert len(_batch(np.zeros((0, 2)), np.zeros((0, 2, 2))).validated(2)) == 0
    Rs = np.broadcast_to(R, (5, 2, 2)).copy()
    Rs[1, 0, 1] = 50.0  # not symmetric
    Rs[3] = [[1.0, 2.0], [2.0, 1.0]]  # symmetric, not positive definite
    zb = z.copy()
    zb[3, 0] = np.nan  # position first: counted as not finite, not as the covariance
    bad = _batch(zb, Rs).validated(2)
    assert bad.rejected == {"covariance not symmetric": 1, "position not finite": 1}
    np.testing.assert_array_equal(bad.z, z[[0, 2, 4]])


@pytest.mark.parametrize("k", [2, 3])
def test_one_pass_validity_agrees_with_the_per_reason_masks(k):
    """The compiled all-plots test is True exactly when the masks reject nothing, for
    batches with one defect of each kind (and none)."""
    from skyfuse.fusion.tracker.plot_validity_kernel import all_plots_valid

    rng = np.random.default_rng(3)
    defects = ["none", "z nan", "z inf", "R nan", "rho nan", "rho negative", "asymmetric",
               "tiny asymmetry", "not positive definite", "zero R"]  # fmt: skip
    for trial in range(200):
        m = int(rng.integers(1, 8))
        z = rng.normal(size=(m, k)) * 1e4
        R = _spd(rng, m, k) * 100.0
        rho = rng.uniform(0, 1e-8, m)
        j, kind = int(rng.integers(m)), defects[trial % len(defects)]
        if kind == "z nan":
            z[j, -1] = np.nan
        elif kind == "z inf":
            z[j, 0] = np.inf
        elif kind == "R nan":
            R[j, 1, 0] = np.nan
        elif kind == "rho nan":
            rho[j] = np.nan
        elif kind == "rho negative":
            rho[j] = -1e-12
        elif kind == "asymmetric":
            R[j, 0, 1] += 1.0
        elif kind == "tiny asymmetry":  # within the tolerance: valid
            R[j, 0, 1] += 1e-9 * abs(R[j]).max()
        elif kind == "not positive definite":
            R[j] = -R[j]
        elif kind == "zero R":
            R[j] = 0.0
        rejected: dict[str, int] = {}
        ok = MeasurementBatch._plot_mask(z, R, rho, rejected)
        assert all_plots_valid(z, R, rho) == bool(ok.all()), kind
        assert (kind in ("none", "tiny asymmetry")) == bool(ok.all()), kind


def _components_reference(t, p, n, m):
    """Connected components of the full track–plot graph by scipy, per track."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    A = sp.csr_matrix((np.ones(len(t)), (t, n + p)), shape=(n + m, n + m))
    return connected_components(A, directed=False)[1][:n]


@pytest.mark.parametrize("case", ["small", "chain", "many links"])
def test_track_clusters_by_propagation_and_fallbacks(case):
    from skyfuse.fusion.association.assignment import track_clusters

    rng = np.random.default_rng(7)
    if case == "chain":  # 300 tracks in one random chain: more rounds than the cap
        n = m = 300
        perm = rng.permutation(n)
        t = np.concatenate([perm[:-1], perm[1:]])
        p = np.concatenate([np.arange(n - 1)] * 2)
    else:
        n, m, e = (30, 50, 40) if case == "small" else (400, 500, 900)
        key = np.unique(rng.integers(0, n, e) * m + rng.integers(0, m, e))
        t, p = key // m, key % m
    got = track_clusters(t, p, n, m)
    ref = _components_reference(t, p, n, m)
    pairs = set(zip(got.tolist(), ref.tolist()))
    assert len(pairs) == len(set(got.tolist())) == len(set(ref.tolist()))
    for lab in np.unique(got):  # the label is the smallest track index of its cluster
        assert lab == np.flatnonzero(got == lab).min()


@pytest.mark.parametrize("k", [2, 3])
def test_imm_pair_likelihoods_against_scipy(k):
    """The compiled per-mode pair likelihoods: ν, symmetrised S, log N against
    scipy.stats.multivariate_normal and the μ-mixed likelihood, per pair and mode."""
    from scipy.stats import multivariate_normal
    from skyfuse.fusion.tracker.density.imm_likelihood_kernel import mode_pair_likelihoods

    rng = np.random.default_rng(11)
    C, r, m = 6, 3, 5
    y = rng.normal(size=(C, r, k)) * 100
    HPH = _spd(rng, C * r, k).reshape(C, r, k, k) * 50
    HPH[0, 0, 0, 1] += 1e-3  # a slightly asymmetric one: symmetrised first
    z, R = rng.normal(size=(m, k)) * 100, _spd(rng, m, k) * 20
    mu = rng.dirichlet(np.ones(r), C)
    pc = rng.integers(0, C, 12)
    pp = rng.integers(0, m, 12)
    nu, S, log_n, mix = mode_pair_likelihoods(pc, pp, y, HPH, z, R, mu)
    for q, (c, i) in enumerate(zip(pc, pp)):
        for j in range(r):
            Sq = HPH[c, j] + R[i]
            Sq = 0.5 * (Sq + Sq.T)
            np.testing.assert_allclose(nu[q, j], z[i] - y[c, j], rtol=1e-15)
            np.testing.assert_allclose(S[q, j], Sq, rtol=1e-15)
            ref = multivariate_normal(np.zeros(k), Sq).logpdf(nu[q, j])
            assert log_n[q, j] == pytest.approx(ref, rel=1e-11, abs=1e-11)
        assert mix[q] == pytest.approx(float(mu[c] @ np.exp(log_n[q])), rel=1e-13)
