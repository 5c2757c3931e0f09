"""The common-target pairing of the registration (fusion.registration.common_target):
the partners found by binary search on the store sorted by track against a brute-force
loop over every (new, stored) pair written from the stated rule."""

import numpy as np
import pytest
from skyfuse.fusion.registration.common_target import PairBuffer, PlotColumns


def columns(rng, k, tracks, radars, t0, t1):
    """k random plots: times on a 0.5 s grid so that ties in |dt| occur."""
    return PlotColumns(
        rng.integers(0, tracks, k), rng.integers(0, radars, k),
        (rng.integers(t0, t1, k) * 500_000_000).astype(np.int64),
        rng.normal(size=(k, 2)), np.tile(np.eye(2), (k, 1, 1)), rng.normal(size=(k, 2, 4)),
        np.zeros((k, 4)), rng.normal(size=(k, 2)), np.tile(np.eye(2), (k, 1, 1)),
    )  # fmt: skip


def brute_partners(new, store, max_dt_ns):
    """Each new plot: the stored plot of the same track, other radar, |dt| <= max, least
    |dt| (ties: lowest stored row); then each stored row keeps the new plot nearest in
    time (ties: lowest new row). Pairs ordered by stored row."""
    best = {}
    for i in range(len(new)):
        cands = [
            (abs(int(new.time[i]) - int(store.time[j])), j)
            for j in range(len(store))
            if new.track[i] == store.track[j]
            and new.radar[i] != store.radar[j]
            and abs(int(new.time[i]) - int(store.time[j])) <= max_dt_ns
        ]
        if cands:
            best[i] = min(cands)
    by_stored = {}
    for i, (c, j) in best.items():
        if j not in by_stored or (c, i) < by_stored[j]:
            by_stored[j] = (c, i)
    pairs = sorted((j, i) for j, (_, i) in by_stored.items())
    return [i for _, i in pairs], [j for j, _ in pairs]


@pytest.mark.parametrize("seed", range(12))
def test_partners_equal_brute_force(seed):
    rng = np.random.default_rng(seed)
    buf = PairBuffer(max_pair_dt=4.0, q=1.0, capacity=10_000)
    store = columns(rng, int(rng.integers(0, 300)), 40, 5, 0, 20)
    new = columns(rng, int(rng.integers(0, 60)), 40, 5, 10, 24)
    ia, ib = buf._partners(new, store)
    ref_a, ref_b = brute_partners(new, store, buf.max_dt_ns)
    assert ia.tolist() == ref_a and ib.tolist() == ref_b


def test_add_pairs_and_replaces():
    """Through add(): a plot of another radar pairs with the stored one and consumes it;
    a newer plot of the same (track, radar) replaces the stored one."""
    buf = PairBuffer(max_pair_dt=4.0, q=0.0, capacity=100)
    one = lambda tr, r, t: PlotColumns(  # noqa: E731
        np.array([tr]), np.array([r]), np.array([t], np.int64), np.zeros((1, 2)),
        np.tile(np.eye(2), (1, 1, 1)), np.zeros((1, 2, 4)), np.zeros((1, 4)), np.zeros((1, 2)),
        np.zeros((1, 2, 2)),
    )  # fmt: skip
    assert len(buf.add(one(7, 0, 0))) == 0 and len(buf.store) == 1
    assert len(buf.add(one(7, 0, 10**9))) == 0 and buf.store.time.tolist() == [10**9]
    pairs = buf.add(one(7, 1, 2 * 10**9))
    assert len(pairs) == 1 and (pairs.a[0], pairs.b[0]) == (1, 0) and len(buf.store) == 0
    assert len(buf.add(one(8, 1, 20 * 10**9))) == 0  # expired: nothing to pair with


def test_pair_residuals_equal_the_equations():
    """The compiled residuals against eq. (2)-(3) written with NumPy matrix products."""
    rng = np.random.default_rng(3)
    A, B = columns(rng, 25, 10, 4, 0, 20), columns(rng, 25, 10, 4, 0, 20)
    A = PlotColumns(A.track, A.radar, A.time, A.z, A.R, A.H, rng.normal(size=(25, 4)), A.v,
                    np.tile(np.diag([4.0, 9.0]), (25, 1, 1)))  # fmt: skip
    buf = PairBuffer(max_pair_dt=4.0, q=2.5, capacity=100)
    got = buf._residuals(A, B)
    dt = (A.time - B.time) * 1e-9
    y = A.z - B.z - A.v * dt[:, None] + np.einsum("kij,kj->ki", A.H, A.applied)
    y -= np.einsum("kij,kj->ki", B.H, B.applied)
    W = (
        A.R
        + B.R
        + dt[:, None, None] ** 2 * A.Pvv
        + (2.5 * np.abs(dt) ** 3 / 3)[:, None, None] * np.eye(2)
    )
    np.testing.assert_allclose(got.y, y, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got.W, W, rtol=1e-12)
    assert got.a.tolist() == A.radar.tolist() and got.b.tolist() == B.radar.tolist()
