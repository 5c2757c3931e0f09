"""LM-IPF step ([LM-IPF] eq. 12-17) over the particle gated table: far-apart tracks give the
IPF inputs exactly; close tracks match the formulas evaluated by brute-force loops."""

from __future__ import annotations

import numpy as np
from scipy import stats
from skyfuse.fusion.models import ConstantVelocity
from skyfuse.fusion.particles.association import (
    ipf_association,
    lm_clutter_density,
    lm_ipf_association,
)
from skyfuse.fusion.tracker.density.particles import ParticleDensity
from skyfuse.fusion.tracker.store import NewTracks, store_for

CV = ConstantVelocity(q=0.75, ndim=2)
R = np.eye(2) * 25.0
G = stats.chi2.ppf(0.99, 2)
PD, PG = 0.8, 0.99


def _table(centres, rng, per_track=4):
    dens = ParticleDensity(CV, 800, seed=3)
    store_for(dens)
    n = len(centres)
    x = np.zeros((n, 4))
    x[:, [0, 2]] = centres
    dens.tracks.append(NewTracks(x, np.tile(np.diag([25.0, 4.0, 25.0, 4.0]), (n, 1, 1))))
    pred = dens.predict(np.arange(n), np.ones(n))
    z = np.vstack([c + rng.normal(size=(per_track, 2)) * 8 for c in centres])
    table = dens.likelihoods(pred, z, np.tile(R, (len(z), 1, 1)), G)
    rho_plot = rng.uniform(1e-6, 5e-6, len(z))
    return table, len(z), rho_plot


def test_far_apart_tracks_give_exactly_the_ipf_inputs():
    rng = np.random.default_rng(1)
    table, m, rho_plot = _table(np.array([[0.0, 0.0], [5e3, 0.0], [0.0, 8e3]]), rng)
    assert len(table) > 6
    psi = np.array([0.9, 0.5, 0.2])
    pdpg = np.full(3, PD * PG)
    rho = rho_plot[table.tp_plot]
    omega = lm_clutter_density(table, m, psi, pdpg, rho)
    assert np.array_equal(omega, rho)
    a = lm_ipf_association(table, m, psi, pdpg, rho)
    b = ipf_association(table, psi, pdpg, rho)
    for u, v in [(a.psi_post, b.psi_post), (a.beta0, b.beta0), (a.beta, b.beta)]:
        assert np.array_equal(u, v)


def _brute_force(table, psi, pdpg, rho_plot):
    """[LM-IPF] eq. 14, 15, 16, 17, 12 with explicit loops over tracks and plots."""
    rows = list(zip(table.tp_track.tolist(), table.tp_plot.tolist()))
    p = {tj: table.p[r] for r, tj in enumerate(rows)}
    tracks = sorted({t for t, _ in rows})
    sel = {t: [j for (u, j) in rows if u == t] for t in tracks}
    P = {}
    for t in tracks:
        total = sum(p[t, l] / rho_plot[l] for l in sel[t])
        for j in sel[t]:
            P[t, j] = pdpg[t] * psi[t] * (p[t, j] / rho_plot[j]) / total
    omega = {}
    for t, j in rows:
        omega[t, j] = rho_plot[j] + sum(
            p[s, j] * P[s, j] / (1 - P[s, j]) for s in tracks if s != t and (s, j) in p
        )
    out = {}
    for t in tracks:
        lam = 1 - pdpg[t] + pdpg[t] * sum(p[t, j] / omega[t, j] for j in sel[t])
        post = lam * psi[t] / (1 - (1 - lam) * psi[t])
        betas = {j: pdpg[t] * p[t, j] / omega[t, j] / lam for j in sel[t]}
        out[t] = (post, (1 - pdpg[t]) / lam, betas)
    return omega, out


def test_close_tracks_match_the_lm_formulas():
    rng = np.random.default_rng(4)
    table, m, rho_plot = _table(np.array([[0.0, 0.0], [30.0, 0.0], [15.0, 25.0]]), rng)
    psi = np.array([0.95, 0.6, 0.3])
    pdpg = np.full(3, PD * PG)
    rho = rho_plot[table.tp_plot]
    omega = lm_clutter_density(table, m, psi, pdpg, rho)
    ref_omega, ref = _brute_force(table, psi, pdpg, rho_plot)
    rows = list(zip(table.tp_track.tolist(), table.tp_plot.tolist()))
    assert np.allclose(omega, [ref_omega[r] for r in rows], rtol=1e-10)
    assert (omega > rho).sum() > len(rows) // 2  # neighbours act as extra clutter
    res = lm_ipf_association(table, m, psi, pdpg, rho)
    for t, (post, beta0, betas) in ref.items():
        assert np.isclose(res.psi_post[t], post, rtol=1e-10)
        assert np.isclose(res.beta0[t], beta0, rtol=1e-10)
        for r, (u, j) in enumerate(rows):
            if u == t:
                assert np.isclose(res.beta[r], betas[j], rtol=1e-10)
