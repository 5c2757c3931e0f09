"""The tracker's compiled passes against references written with NumPy or loops here:
the two-point pairing with the buffer's expiry, the pairs of tracks sharing a plot, the
screened termination test of the existence chain, the track × plot table, the slots
of a set of track rows and their renumbering, the LM-ITS modified clutter density, the
IPDA/ITS update, the existence chain's update, each track's most likely plot and the
re-identification fixes."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.tracker.component_slots import ComponentSlots
from skyfuse.fusion.tracker.components import Mixture
from skyfuse.fusion.tracker.density.gaussian_mixture import track_table
from skyfuse.fusion.tracker.existence import markov_chain_one, markov_chain_two
from skyfuse.fusion.tracker.initiation import PlotBuffer, pair_plots
from skyfuse.fusion.tracker.ipda import single_target
from skyfuse.fusion.tracker.lm_its import modified_clutter_density
from skyfuse.fusion.tracker.management import shared_plot_pairs
from skyfuse.fusion.tracker.phases import most_likely_plots
from skyfuse.fusion.tracker.reidentification import FIX_HORIZON, update_fix_columns


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


def _table(rng, n=8, m=12, rows=30):
    """A random track × plot table sorted by track, some tracks without rows."""
    pairs = sorted({(int(a), int(b)) for a, b in rng.integers(0, (n, m), (rows, 2))})
    tp_track, tp_plot = (np.array(c, np.int64) for c in zip(*pairs))
    return tp_track, tp_plot, n, m


def test_renumbered_slots_against_cumsum():
    rng = np.random.default_rng(11)
    track = rng.integers(0, 10, 40)
    mix = Mixture(track, rng.random(40), rng.normal(size=(40, 2)), np.ones((40, 2, 2)),
                  np.zeros((40, 1), np.int64))  # fmt: skip
    slots = ComponentSlots.holding(mix)
    mask = rng.random(10) < 0.6
    slots.keep(mask)
    new_row = np.where(mask, np.cumsum(mask) - 1, -1)
    live = slots.live()
    np.testing.assert_array_equal(live.track, new_row[track[mask[track]]])
    np.testing.assert_array_equal(live.x, mix.x[mask[track]])


@pytest.mark.parametrize("prior", ["canonical", "thesis"])
def test_modified_clutter_density_against_numpy(prior):
    rng = np.random.default_rng(5)
    tp_track, tp_plot, n, m = _table(rng)
    p = rng.random(len(tp_track)) * 1e-6
    p[tp_track == tp_track[0]] = 0.0  # a track whose likelihoods all underflowed
    rho = rng.uniform(1e-8, 1e-7, len(tp_track))
    psi, pdpg = rng.random(n), rng.uniform(0.5, 0.95, n)
    expected = pdpg[tp_track] * psi[tp_track] * p
    rho_prior = rho
    if prior == "thesis":
        rho_prior = rho + np.bincount(tp_plot, weights=expected, minlength=m)[tp_plot] - expected
    r = p / rho_prior
    rsum = np.bincount(tp_track, weights=r, minlength=n)[tp_track]
    P = np.minimum(pdpg[tp_track] * psi[tp_track] * r / np.where(rsum > 0, rsum, 1.0), 1 - 1e-12)
    term = p * P / (1.0 - P)
    per_plot = np.bincount(tp_plot, weights=term, minlength=m)[tp_plot]
    ref = rho + np.maximum(per_plot - term, 0.0)
    out = modified_clutter_density(tp_track, tp_plot, m, p, rho, psi, pdpg, prior)
    assert np.array_equal(out, ref)  # the same operations in the same order
    with pytest.raises(ValueError):
        modified_clutter_density(tp_track, tp_plot, m, p, rho, psi, pdpg, "other")


def test_single_target_against_the_formulas():
    rng = np.random.default_rng(6)
    tp_track, _, n, _ = _table(rng)
    ratio, psi, pdpg = rng.random(len(tp_track)) * 5, rng.random(n), rng.uniform(0.5, 0.95, n)
    res = single_target(psi, pdpg, tp_track, ratio)
    lam = 1.0 - pdpg + pdpg * np.bincount(tp_track, weights=ratio, minlength=n)  # (5.16)
    np.testing.assert_array_equal(res.psi_post, lam * psi / (1.0 - (1.0 - lam) * psi))
    np.testing.assert_array_equal(res.beta0, (1.0 - pdpg) / lam)
    np.testing.assert_array_equal(res.beta, pdpg[tp_track] * ratio / lam[tp_track])
    # β₀ + Σ β = 1 per track (2.38)
    total = res.beta0 + np.bincount(tp_track, weights=res.beta, minlength=n)
    np.testing.assert_allclose(total, 1.0, rtol=1e-12)


def test_existence_update_renormalises_the_undetectable_state():
    chain = markov_chain_two(0.98, 0.9, 0.05, 0.1)
    rng = np.random.default_rng(8)
    state = rng.dirichlet(np.ones(3), 20)[:, :2]
    state[0] = [1.0, 0.0]  # 1 − p_obs = 0: scale 1
    post = rng.random(20)
    out = chain.update(state, post)
    scale = np.ones(20)
    scale[1:] = (1.0 - post[1:]) / (1.0 - state[1:, 0])
    np.testing.assert_array_equal(out[:, 0], post)
    np.testing.assert_array_equal(out[:, 1], np.clip(state[:, 1] * scale, 0.0, 1.0))


def test_most_likely_plots_against_lexsort():
    rng = np.random.default_rng(9)
    tp_track, tp_plot, n, _ = _table(rng, rows=40)
    beta = rng.integers(0, 4, len(tp_track)) / 4.0  # ties
    beta[3] = np.nan
    beta0 = rng.random(n) * 0.5
    sel = np.sort(rng.choice(30, n, replace=False))
    out = most_likely_plots(30, sel, beta0, beta, tp_track, tp_plot)
    ref = np.full(30, -1)
    for t in range(n):
        rows = np.flatnonzero(tp_track == t)
        if len(rows):
            best = rows[np.argsort(-beta[rows], kind="stable")[0]]  # NaN last, first of equals
            if beta[best] > beta0[t]:
                ref[sel[t]] = tp_plot[best]
    assert (ref >= 0).sum() > 2 and np.array_equal(out, ref)


def test_update_fix_columns_keeps_the_better_fix():
    rng = np.random.default_rng(10)
    n, q = 6, 4.0
    x = rng.normal(size=(n, 4))
    A = rng.normal(size=(n, 4, 4))
    P = A @ A.transpose(0, 2, 1) + np.eye(4)
    fix_x, fix_t = np.zeros((n, 4)), np.zeros(n, np.int64)
    fix_P = P * rng.choice([0.01, 100.0], n)[:, None, None]
    hit, t = np.array([0, 2, 3, 5]), np.array([2, 3, 1, 9]) * 10**9
    before = fix_P.copy()
    update_fix_columns(hit, t, x, P, fix_x, fix_P, fix_t, FIX_HORIZON, q)

    def worst(P1, dt):  # largest per-axis position variance after dt (R1)
        return max(P1[p, p] + 2 * dt * P1[p, p + 1] + dt**2 * P1[p + 1, p + 1] + q * dt**3 / 3
                   for p in (0, 2))  # fmt: skip

    for i, h in enumerate(hit):
        kept = worst(before[h], t[i] * 1e-9 + FIX_HORIZON) < worst(P[h], FIX_HORIZON)
        assert np.array_equal(fix_P[h], before[h] if kept else P[h])
        assert fix_t[h] == (0 if kept else t[i])
    assert {bool(fix_t[h] == 0) for h in hit} == {True, False}
    assert fix_t[1] == 0 and fix_t[4] == 0  # rows not hit stay
