"""The tracker's compiled passes against references written with NumPy or loops here:
the two-point pairing with the buffer's expiry, the pairs of tracks sharing a plot, the
screened termination test of the existence chain, the track × plot table, and the slots
of a set of track rows."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.tracker.component_slots import ComponentSlots
from skyfuse.fusion.tracker.components import Mixture
from skyfuse.fusion.tracker.density.gaussian_mixture import track_table
from skyfuse.fusion.tracker.existence import markov_chain_one, markov_chain_two
from skyfuse.fusion.tracker.initiation import PlotBuffer, pair_plots
from skyfuse.fusion.tracker.management import shared_plot_pairs


def test_pair_plots_against_every_pair():
    rng = np.random.default_rng(3)
    buf = PlotBuffer.empty(2)
    nb, m = 60, 25
    bz = rng.uniform(0, 5000, (nb, 2))
    bt = rng.integers(0, 6, nb) * 10**9
    buf.add(bz, np.broadcast_to(100 * np.eye(2), (nb, 2, 2)).copy(), bt, np.arange(nb))
    z = rng.uniform(0, 5000, (m, 2))
    t = np.full(m, 6 * 10**9) + rng.integers(0, 2, m) * 10**9 // 2
    v_max, min_dt, max_dt, now = 350.0, 0.5, 4.0, 6 * 10**9
    old, new, dt, stay = pair_plots(buf, z, t, v_max, min_dt, max_dt, now)
    alive = (now - bt) * 1e-9 <= max_dt
    ref = sorted(
        (i, j)
        for i in range(m)
        for j in range(nb)
        if alive[j]
        and min_dt <= (t[i] - bt[j]) * 1e-9 <= max_dt
        and np.hypot(*(z[i] - bz[j])) <= v_max * (t[i] - bt[j]) * 1e-9
    )
    assert len(ref) > 5 and sorted(zip(new, old)) == ref
    np.testing.assert_array_equal(dt, (t[new] - bt[old]) * 1e-9)
    assert list(new) == sorted(new)  # in the order of the new plots
    np.testing.assert_array_equal(stay, alive & ~np.isin(np.arange(nb), old))


def test_shared_plot_pairs_against_every_pair():
    rng = np.random.default_rng(4)
    track = rng.permutation(40)[:30]
    plot = rng.integers(0, 12, 30)
    a, b = shared_plot_pairs(track, plot)
    ref = sorted(
        {(min(track[i], track[j]), max(track[i], track[j]))
         for i in range(30) for j in range(30) if i != j and plot[i] == plot[j]}
    )  # fmt: skip
    assert len(ref) > 3 and list(zip(a, b)) == ref


@pytest.mark.parametrize(
    "chain", [markov_chain_one(0.98, 0.0), markov_chain_two(0.98, 0.01, 0.05, 0.5)]
)
def test_existence_below_is_the_prediction_where_it_may_be_below(chain):
    rng = np.random.default_rng(5)
    n = 400
    state = np.column_stack([rng.uniform(0, 0.5, n), rng.uniform(0, 0.4, n)])
    dt = rng.uniform(0, 600, n)
    also = rng.random(n) < 0.1
    level = 0.01
    psi = chain.existence_below(state, dt, level, also)
    exact = chain.existence(chain.predict(state, dt))
    near = (exact < level + 1e-9) | also
    assert near.sum() > 20 and (~near).sum() > 20
    np.testing.assert_array_equal(psi[near], exact[near])
    assert (psi[~near] == 1.0).all()


def test_track_table_against_np_unique():
    rng = np.random.default_rng(6)
    C, m, P = 30, 9, 70
    loc = np.sort(rng.integers(0, 8, C))
    comp = rng.integers(0, C, P)
    plot = rng.integers(0, m, P)
    w, p = rng.random(C), rng.random(P)
    tp_track, tp_plot, p_track, row = track_table(loc, comp, plot, w, p, m)
    keys, inv = np.unique(loc[comp] * m + plot, return_inverse=True)
    np.testing.assert_array_equal(tp_track, keys // m)
    np.testing.assert_array_equal(tp_plot, keys % m)
    np.testing.assert_array_equal(row, inv.reshape(-1))
    ref = np.zeros(len(keys))
    for q in range(P):  # in pair order, as the sum of 5.10 is taken
        ref[inv[q]] += w[comp[q]] * p[q]
    np.testing.assert_array_equal(p_track, ref)


def test_rows_of_slots_against_a_mask():
    rng = np.random.default_rng(7)
    track = rng.integers(0, 10, 50)
    mix = Mixture(track, rng.random(50), rng.normal(size=(50, 4)), np.ones((50, 4, 4)),
                  np.zeros((50, 1), np.int64))  # fmt: skip
    slots = ComponentSlots.holding(mix)
    slots.replace(np.isin(np.arange(10), [2, 5]), mix.take(np.flatnonzero(np.isin(track, [2, 5]))))
    rows = np.array([1, 2, 5, 8])
    comp, loc = slots.rows(rows, 10)
    live = slots.live()
    ref = np.flatnonzero(np.isin(live.track, rows))
    np.testing.assert_array_equal(comp.track, live.track[ref])
    np.testing.assert_array_equal(comp.x, live.x[ref])
    np.testing.assert_array_equal(loc, np.searchsorted(rows, live.track[ref]))
    every, _ = slots.rows(np.arange(10), 10)
    np.testing.assert_array_equal(every.track, live.track)
