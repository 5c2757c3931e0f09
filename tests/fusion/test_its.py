"""ITS with Singer N-scan memory: component counts before pruning ([thesis]
(5.26) / (5.1a)) and the merge by moment matching."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig
from skyfuse.fusion.tracker.components import Mixture, singer_merge

R = 25.0 * np.eye(2)
X0 = np.array([0.0, 10.0, 0.0, 5.0])
P0 = np.diag([400.0, 100.0, 400.0, 100.0])


def run_counts(depth, sizes, seed=0):
    """Scans with m_k plots clustered within ±3 m of the target, so every component
    selects every plot; returns the merged (pre-pruning) component count per scan."""
    rng = np.random.default_rng(seed)
    cfg = TrackerConfig(
        motion="cv",
        tracker="its",
        depth=depth,
        q=0.75,
        initiation="none",
        prune_threshold=0.0,
        max_components=100_000,
        clutter="known",
    )
    tr = Tracker(cfg)
    tr.add_track(X0, P0, 0, existence=0.5)
    counts = []
    truth = X0.copy()
    for k, m in enumerate(sizes, start=1):
        truth = truth + np.array([10.0, 0, 5.0, 0])
        z = truth[[0, 2]] + rng.uniform(-3, 3, (m, 2))
        out = tr.step(MeasurementBatch(k * 10**9, "r", z, R, 0.9, 1e-4))
        assert (out.stats["gated_pairs"] > 0) == (m > 0)
        counts.append(out.stats["components_merged"])
        assert list(tr.component_counts().values()) == [counts[-1]]
    return counts


@pytest.mark.parametrize("sizes", [(3, 2, 4), (1, 5, 2), (2, 0, 3)])
def test_depth_one_gives_one_plus_m(sizes):
    assert run_counts(1, sizes) == [1 + m for m in sizes]


@pytest.mark.parametrize("sizes", [(3, 2, 4), (1, 5, 2), (2, 0, 3)])
def test_depth_two_gives_product_of_two_scans(sizes):
    expected = [1 + sizes[0]] + [(1 + sizes[k]) * (1 + sizes[k - 1]) for k in (1, 2)]
    assert run_counts(2, sizes) == expected


def test_depth_three_bound_and_depth_zero_single_gaussian():
    sizes = (2, 3, 1, 2)
    c3 = run_counts(3, sizes)
    assert c3[2] == 3 * 4 * 2 and c3[3] == 3 * 2 * 4  # Π_{j<N}(1 + m_{k−j})
    assert run_counts(0, sizes) == [1, 1, 1, 1]


def test_singer_merge_of_one_component_per_track_in_any_order():
    """GNN/IPDA children (one per track, tracks out of order, as the null and updated
    children come): each is its own group, returned in track order with its history."""
    rng = np.random.default_rng(5)
    order = rng.permutation(6)
    A = rng.normal(size=(6, 4, 4))
    mix = Mixture(order.copy(), rng.uniform(0.1, 1, 6), rng.normal(size=(6, 4)),
                  A @ A.transpose(0, 2, 1), rng.integers(0, 9, (6, 3)))  # fmt: skip
    out = singer_merge(mix)
    back = np.argsort(order)
    np.testing.assert_array_equal(out.track, np.arange(6))
    np.testing.assert_array_equal(out.w, mix.w[back])
    np.testing.assert_array_equal(out.x, mix.x[back])
    np.testing.assert_array_equal(out.hist, mix.hist[back])
    np.testing.assert_allclose(out.P, mix.P[back], rtol=1e-15)


def test_singer_merge_moment_matching_by_hand():
    # two components of track 0 share the history (5,), one has (6,); track 1 alone
    x = np.array([[0.0, 1.0], [2.0, 3.0], [10.0, 0.0], [7.0, 7.0]])
    P = np.stack([np.eye(2), 2 * np.eye(2), np.eye(2), np.eye(2)])
    mix = Mixture(
        np.array([0, 0, 0, 1]),
        np.array([0.2, 0.6, 0.2, 1.0]),
        x,
        P,
        np.array([[5], [5], [6], [5]]),
    )
    out = singer_merge(mix)
    assert len(out) == 3
    i = np.flatnonzero((out.track == 0) & (out.hist[:, 0] == 5))[0]
    w = 0.8
    xm = (0.2 * x[0] + 0.6 * x[1]) / w
    Pm = (
        0.2 * (P[0] + np.outer(x[0] - xm, x[0] - xm))
        + 0.6 * (P[1] + np.outer(x[1] - xm, x[1] - xm))
    ) / w
    assert out.w[i] == pytest.approx(w)
    np.testing.assert_allclose(out.x[i], xm)
    np.testing.assert_allclose(out.P[i], Pm)
