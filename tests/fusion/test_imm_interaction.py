"""The one IMM interaction (mixing) step against explicit sums over i and j ([Dikić]
eq. 15-17 written out per IMM), for three modes in one layout and in three layouts
(CV, Singer, coordinated turn, mixed in the Singer layout), with one transition matrix
for all IMMs and one per IMM."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.filters.imm_interaction import interact, mixing_probabilities
from skyfuse.fusion.models import ConstantVelocity, CoordinatedTurn, Singer
from skyfuse.fusion.models.conversions import from_common, to_common


def _spd(rng, d, scale=1.0):
    A = rng.normal(size=(d, d))
    return (A @ A.T + d * np.eye(d)) * scale


def _brute_force(mu, Pi, xc, Pc):
    """c_j, μ_{i|j}, x̂⁰_j, P⁰_j of one IMM by explicit loops (common layout)."""
    r = len(mu)
    c = [sum(Pi[i, j] * mu[i] for i in range(r)) for j in range(r)]
    w = [[Pi[i, j] * mu[i] / c[j] for j in range(r)] for i in range(r)]
    x0, P0 = [], []
    for j in range(r):
        xj = sum(w[i][j] * xc[i] for i in range(r))
        Pj = sum(w[i][j] * (Pc[i] + np.outer(xc[i] - xj, xc[i] - xj)) for i in range(r))
        x0.append(xj)
        P0.append(Pj)
    return np.array(c), np.array(w), x0, P0


def _states(rng, models, n):
    xs, Ps = [], []
    for m in models:
        x = rng.normal(0, 100, (n, m.dim))
        if isinstance(m, CoordinatedTurn):  # (x, y, ψ, ω, v): a plausible course, rate, speed
            x[:, 2] = rng.uniform(-3, 3, n)
            x[:, 3] = rng.uniform(-0.05, 0.05, n)
            x[:, 4] = rng.uniform(150, 300, n)
        xs.append(x)
        Ps.append(np.stack([_spd(rng, m.dim, 10.0) for _ in range(n)]))
    return xs, Ps


@pytest.mark.parametrize("layouts", ["one", "three"])
@pytest.mark.parametrize("per_imm", [False, True])
def test_interaction_equals_explicit_sums_over_i_and_j(layouts, per_imm):
    rng = np.random.default_rng(7)
    n = 5
    if layouts == "one":
        models = [ConstantVelocity(q=q) for q in (1.0, 25.0, 400.0)]
    else:
        models = [ConstantVelocity(q=4.0), Singer(10.0, 20.0), CoordinatedTurn(2.0, 0.02)]
    xs, Ps = _states(rng, models, n)
    mu = rng.dirichlet(np.ones(3), n)
    base = np.array([[0.8, 0.15, 0.05], [0.1, 0.7, 0.2], [0.25, 0.05, 0.7]])
    Pi = rng.dirichlet(np.ones(3) * 2, (n, 3)) if per_imm else base
    x0, P0, c = interact(mu, Pi, xs, Ps, models)
    c2, w2 = mixing_probabilities(mu, Pi)
    for k in range(n):
        Pik = Pi[k] if per_imm else Pi
        common = [
            to_common(m, xs[j][k : k + 1], Ps[j][k : k + 1]) if layouts == "three" else
            (xs[j][k : k + 1], Ps[j][k : k + 1])
            for j, m in enumerate(models)
        ]  # fmt: skip
        ref_c, ref_w, ref_x, ref_P = _brute_force(
            mu[k], Pik, [a[0] for a, _ in common], [b[0] for _, b in common]
        )
        np.testing.assert_allclose(c[k], ref_c, rtol=1e-13)
        np.testing.assert_allclose(c2[k], ref_c, rtol=1e-13)
        np.testing.assert_allclose(w2[k], ref_w, rtol=1e-13)
        np.testing.assert_allclose(ref_w.sum(axis=0), 1.0, rtol=1e-13)
        for j, m in enumerate(models):
            xj, Pj = ref_x[j][None], ref_P[j][None]
            if layouts == "three":
                xj, Pj = from_common(m, xj, Pj)
            np.testing.assert_allclose(x0[j][k], xj[0], rtol=1e-10, atol=1e-9)
            np.testing.assert_allclose(P0[j][k], Pj[0], rtol=1e-10, atol=1e-9)


def test_one_mode_is_left_alone_and_a_certain_mode_is_its_own_mix():
    """r = 1: no interaction (the states are returned as they are, c = μ Π = 1); and
    with Π = I every mode mixes only with itself (x̂⁰_j = x̂_j, P⁰_j = P_j)."""
    rng = np.random.default_rng(8)
    cv = ConstantVelocity(q=4.0)
    xs, Ps = _states(rng, [cv], 3)
    x0, P0, c = interact(np.ones((3, 1)), np.eye(1), xs, Ps, [cv])
    assert x0[0] is xs[0] and P0[0] is Ps[0]
    np.testing.assert_array_equal(c, 1.0)
    models = [ConstantVelocity(q=1.0), ConstantVelocity(q=100.0)]
    xs, Ps = _states(rng, models, 3)
    mu = rng.dirichlet(np.ones(2), 3)
    x0, P0, c = interact(mu, np.eye(2), xs, Ps, models)
    np.testing.assert_allclose(c, mu, rtol=1e-15)
    for j in range(2):
        np.testing.assert_allclose(x0[j], xs[j], rtol=1e-13)
        np.testing.assert_allclose(P0[j], 0.5 * (Ps[j] + Ps[j].swapaxes(1, 2)), rtol=1e-13)
