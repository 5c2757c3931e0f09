"""LM-ITS / LM-IPDA ([thesis] §6.2.2-6.2.3): ≡ ITS when tracks are far apart; the modified clutter
density (6.12-6.14) against a hand computation when they share plots."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig
from skyfuse.fusion.tracker.lm_its import modified_clutter_density

R = 25.0 * np.eye(2)
P0 = np.diag([50.0, 50.0, 50.0, 50.0])


def run(kind, starts, scans=10, seed=5, spread=60.0):
    rng = np.random.default_rng(seed)
    cfg = TrackerConfig(
        motion="cv",
        tracker=kind,
        depth=2,
        q=0.75,
        initiation="none",
        clutter="known",
        prune_threshold=1e-4,
    )
    tr = Tracker(cfg)
    for x in starts:
        tr.add_track(x, P0, 0, existence=0.4)
    truths = [np.array(x, float) for x in starts]
    outs = []
    for k in range(1, scans + 1):
        plots = []
        for i, t in enumerate(truths):
            truths[i] = t + np.array([t[1], 0, t[3], 0])
            if rng.random() < 0.85:
                plots.append(truths[i][[0, 2]] + rng.normal(0, 5, 2))
            plots.extend(truths[i][[0, 2]] + rng.uniform(-spread, spread, (3, 2)))
        outs.append(tr.step(MeasurementBatch(k * 10**9, "r", np.array(plots), R, 0.85, 2e-4)))
    return outs


@pytest.mark.parametrize("kind", ["lmits", "jits"])
def test_multi_target_its_equals_its_when_tracks_are_far_apart(kind):
    starts = [[0, 10, 0, 5], [5000, -10, 3000, 2], [-4000, 3, 9000, -8]]
    for a, b in zip(run("its", starts), run(kind, starts)):
        np.testing.assert_array_equal(a.ids, b.ids)
        np.testing.assert_allclose(a.existence, b.existence, rtol=1e-12)
        np.testing.assert_allclose(a.states, b.states, rtol=1e-12, atol=1e-9)


def test_lmits_differs_from_its_when_tracks_share_plots():
    starts = [[0, 10, 0, 5], [40, 10, 30, 5]]
    a, b = run("its", starts)[-1], run("lmits", starts)[-1]
    assert len(a) == len(b) == 2
    assert not np.allclose(a.existence, b.existence, rtol=1e-6)


def test_modified_clutter_density_by_hand():
    # tracks 0 and 1 both gate plot 0; track 0 also gates plot 1
    tp_track = np.array([0, 0, 1])
    tp_plot = np.array([0, 1, 0])
    p = np.array([1e-3, 4e-4, 2e-3])
    rho = np.array([1e-4, 1e-4, 1e-4])
    psi = np.array([0.9, 0.6])
    pdpg = np.array([0.8, 0.7])
    out = modified_clutter_density(tp_track, tp_plot, 2, p, rho, psi, pdpg, "canonical")
    # (6.12) canonical: P^σ_i = P_D P_G ψ^σ (p^σ_i/ρ_i) / Σ_j p^σ_j/ρ_j
    P00 = 0.8 * 0.9 * (1e-3 / 1e-4) / (1e-3 / 1e-4 + 4e-4 / 1e-4)
    P10 = 0.7 * 0.6 * 1.0  # track 1 gates only plot 0
    # (6.14): ρ̃ for track 0 at plot 0 adds track 1's term and vice versa
    assert out[0] == pytest.approx(1e-4 + 2e-3 * P10 / (1 - P10))
    assert out[1] == pytest.approx(1e-4)
    assert out[2] == pytest.approx(1e-4 + 1e-3 * P00 / (1 - P00))
    # thesis prior (6.13): ρ^σ_i adds the other tracks' P_D P_G ψ p
    th = modified_clutter_density(tp_track, tp_plot, 2, p, rho, psi, pdpg, "thesis")
    rho0 = 1e-4 + 0.7 * 0.6 * 2e-3  # for track 0 at plot 0
    P00t = 0.8 * 0.9 * (1e-3 / rho0) / (1e-3 / rho0 + 4e-4 / 1e-4)
    assert th[2] == pytest.approx(1e-4 + 1e-3 * P00t / (1 - P00t))


def test_a_track_whose_gated_likelihoods_all_underflowed_adds_no_clutter():
    """Track 1 gates plots 0 and 1 with likelihood 0 (a particle cloud far from them):
    (6.12) has 0/0 for it; it must give those plots no prior probability, so ρ̃ of track
    0's rows is ρ plus nothing from track 1, and every value is finite (a NaN here became
    a NaN existence on the Barcelona recording with lmipf)."""
    tp_track, tp_plot = np.array([0, 1, 1]), np.array([0, 0, 1])
    p = np.array([2e-9, 0.0, 0.0])
    rho = np.full(3, 1e-9)
    out = modified_clutter_density(
        tp_track, tp_plot, 2, p, rho, np.array([0.9, 0.9]), np.array([0.85, 0.85])
    )
    assert np.isfinite(out).all()
    # track 0's own row: other tracks' terms only (track 1's are 0); track 1's row on
    # plot 0: track 0's term p P / (1 - P) with P = P_D P_G ψ (its only gated plot)
    P0 = min(0.85 * 0.9, 1.0 - 1e-12)
    assert out[0] == rho[0]
    assert out[1] == pytest.approx(rho[1] + 2e-9 * P0 / (1.0 - P0), rel=1e-12)
    assert out[2] == rho[2]
