"""The performance rewrites of tracker hot paths agree with straightforward references
(full-graph connected components, np.add.at, np.unique(axis=0), eigenvalues), and the
scaling benchmark's case runner works at tiny sizes."""

from __future__ import annotations

import importlib.util
import sys

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from service_support import ROOT
from skyfuse.fusion.filters.cholesky_kernels import positive_definite
from skyfuse.fusion.tracker import components as comp
from skyfuse.fusion.tracker.jits import clusters


def _same_partition(a: np.ndarray, b: np.ndarray) -> bool:
    """Two labelings describe the same partition."""
    pairs = set(zip(a.tolist(), b.tolist()))
    return len(pairs) == len(set(a.tolist())) == len(set(b.tolist()))


def test_clusters_match_full_graph_components():
    rng = np.random.default_rng(5)
    for _ in range(30):
        n, m = int(rng.integers(1, 40)), int(rng.integers(1, 60))
        e = int(rng.integers(0, 80))
        t, p = rng.integers(0, n, e), rng.integers(0, m, e)
        key = np.unique(t * m + p)
        t, p = key // m, key % m
        A = sp.csr_matrix((np.ones(len(t)), (t, n + p)), shape=(n + m, n + m))
        _, ref = connected_components(A, directed=False)
        got = clusters(t, p, n, m)
        assert got.shape == (n,) and got.min() >= 0 and got.max() < 2 * n
        assert _same_partition(got, ref[:n])


def test_segment_sum_matches_add_at():
    rng = np.random.default_rng(1)
    for shape in ((50,), (50, 4), (50, 4, 4)):
        v = rng.normal(size=shape)
        g = rng.integers(0, 12, 50)
        ref = np.zeros((15, *shape[1:]))
        np.add.at(ref, g, v)
        assert np.allclose(comp.segment_sum(v, g, 15), ref, rtol=0, atol=1e-12)
    assert comp.segment_sum(np.zeros((0, 4)), np.zeros(0, np.int64), 3).shape == (3, 4)


def test_moment_match_single_components_and_singer_grouping():
    rng = np.random.default_rng(2)
    n, d = 7, 4
    x = rng.normal(size=(n, d))
    A = rng.normal(size=(n, d, d))
    P = A @ np.swapaxes(A, 1, 2) + np.eye(d)
    w1 = rng.random(n)
    W, xm, Pm = comp.moment_match(w1, x, P, np.arange(n), n)
    assert np.allclose(W, w1) and np.allclose(xm, x) and np.allclose(Pm, P)
    # Singer merge groups exactly as np.unique over (track, history) rows
    C = 60
    track = rng.integers(0, 5, C)
    hist = rng.integers(0, 3, (C, 2))
    xs = rng.normal(size=(C, d))
    Ps = np.broadcast_to(np.eye(d), (C, d, d)).copy()
    w = rng.random(C)
    merged = comp.singer_merge(comp.Mixture(track, w, xs, Ps, hist))
    keys, inv = np.unique(np.column_stack([track, hist]), axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    assert np.array_equal(np.column_stack([merged.track, merged.hist]), keys)
    assert np.allclose(merged.w, np.bincount(inv, weights=w))
    ref_x = np.stack([(w[inv == g, None] * xs[inv == g]).sum(0) / w[inv == g].sum()
                      for g in range(len(keys))])  # fmt: skip
    assert np.allclose(merged.x, ref_x)


def test_positive_definite_matches_eigenvalues():
    rng = np.random.default_rng(3)
    for k in (2, 3):
        A = rng.normal(size=(400, k, k))
        S = 0.5 * (A + np.swapaxes(A, 1, 2))  # symmetric, often indefinite
        S[:100] = A[:100] @ np.swapaxes(A[:100], 1, 2) + 0.1 * np.eye(k)  # definite
        ref = np.linalg.eigvalsh(S)[:, 0] > 0
        assert np.array_equal(positive_definite(S), ref)
        assert ref.sum() >= 100 and (~ref).sum() > 50


def test_scaling_case_tiny():
    spec = importlib.util.spec_from_file_location("scaling", ROOT / "benchmarks" / "scaling.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["scaling"] = mod
    spec.loader.exec_module(mod)
    r = mod.run_case("lmits", 5, 20, scans=2, warmup=2)
    assert r["targets_held"] == 5
    assert r["ms_per_scan_median"] > 0 and r["peak_memory_mb"] > 0
    p = mod.profile_case("gnn", 5, 20, scans=2, warmup=1)
    assert abs(sum(p["percent"].values()) - 100.0) < 1.0
