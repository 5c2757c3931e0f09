"""Reachability gate of the IMM density (fusion/tracker/density/imm_mixture.py ReachGate,
eq. C1): after a coast, a plot farther from the last fix than
v_max Δt + √g (σ_f + σ_R) is not gated however loose the prediction has grown.
References: the reach written out by hand with the closed-form largest eigenvalue of a
2 × 2 covariance, and the same density with the gate off."""

import numpy as np
from scipy.stats import chi2
from skyfuse.fusion.tracker import TrackerConfig
from skyfuse.fusion.tracker.density.imm_mixture import imm_density
from skyfuse.fusion.tracker.store import NewTracks, store_for

G = float(chi2.ppf(0.99, 2))


def _lambda_max(P2):
    """Largest eigenvalue of [[a, b], [b, c]]: (a + c)/2 + √(((a − c)/2)² + b²)."""
    a, b, c = P2[0, 0], P2[0, 1], P2[1, 1]
    return (a + c) / 2 + np.sqrt(((a - c) / 2) ** 2 + b * b)


def _coasted(reach_gate: bool, coasts: int = 3, dt: float = 4.0):
    """A track whose velocity is nearly unknown (σ_v 400 m/s), then ``coasts`` misses."""
    d = imm_density(TrackerConfig(reach_gate=reach_gate), "ct")
    x = np.array([[0.0, 150.0, 0.0, 0.0]])
    P = np.array([[[70.0**2, 0, 500.0, 0], [0, 400.0**2, 0, 0], [500.0, 0, 40.0**2, 0],
                   [0, 0, 0, 400.0**2]]])  # fmt: skip
    store_for(d).append(NewTracks(x, P))
    rows = np.array([0])
    for _ in range(coasts):
        pred = d.predict(rows, np.array([dt]))
        table = d.likelihoods(pred, np.zeros((0, 2)), np.zeros((0, 2, 2)), G)
        d.update(pred, table, np.ones(1), np.zeros(0))
    return d, x[0], P[0]


def _gated(d, z, R, dt=4.0):
    pred = d.predict(np.array([0]), np.array([dt]))
    table = d.likelihoods(pred, z, R, G)
    return set(table.tp_plot.tolist())


def test_plots_beyond_the_reach_are_not_gated():
    cfg = TrackerConfig()
    d_on, x, P = _coasted(True)
    d_off, _, _ = _coasted(False)
    R = np.array([[90.0**2, 300.0], [300.0, 30.0**2]])
    # the reach after three 4 s coasts and a fourth prediction of 4 s, by hand
    since = 16.0
    sf = np.sqrt(_lambda_max(P[np.ix_([0, 2], [0, 2])]))
    sr = np.sqrt(_lambda_max(R))
    reach = cfg.v_max * since + np.sqrt(G) * (sf + sr)
    u = np.array([0.6, 0.8])  # a direction off the axes
    z = np.array([x[[0, 2]] + (reach - 30.0) * u, x[[0, 2]] + (reach + 30.0) * u])
    Rs = np.array([R, R])
    # without the gate the loose prediction (σ_v 400 m/s) holds both plots
    assert _gated(d_off, z, Rs) == {0, 1}
    assert _gated(d_on, z, Rs) == {0}


def _hit(d, x, z, R):
    pred = d.predict(np.array([0]), np.array([4.0]))
    table = d.likelihoods(pred, z, R, G)
    assert table.tp_plot.tolist() == [0]
    d.update(pred, table, np.array([0.0]), np.array([1.0]))  # a certain hit


def test_a_plot_resets_the_fix():
    d, x, P = _coasted(True, coasts=5)
    d_off, _, _ = _coasted(False, coasts=5)
    R = np.diag([50.0**2, 50.0**2])[None]
    z = x[[0, 2]][None] + np.array([[600.0, 0.0]])  # reachable: 150 m/s over 24 s
    _hit(d, x, z, R)
    _hit(d_off, x, z, R)
    # the new fix is the updated estimate, its clock restarts
    xu, Pu = d.estimate(np.array([0]))
    np.testing.assert_allclose(d.tracks.reach_p[0], xu[0, [0, 2]])
    assert d.tracks.reach_since[0] == 0.0
    sf = np.sqrt(_lambda_max(Pu[0][np.ix_([0, 2], [0, 2])]))
    np.testing.assert_allclose(d.tracks.reach_sigma[0], sf)
    # 4 s later: a plot 200 m beyond the new reach, well inside the old fix's reach
    new_reach = 350.0 * 4.0 + np.sqrt(G) * (sf + 50.0)
    old_reach = 350.0 * 28.0 + np.sqrt(G) * (np.sqrt(_lambda_max(P[np.ix_([0, 2], [0, 2])])) + 50.0)
    far = xu[0, [0, 2]][None] + np.array([[0.0, new_reach + 200.0]])
    assert np.linalg.norm(far[0] - x[[0, 2]]) < old_reach - 200.0
    assert _gated(d_off, far, R) == {0}
    assert _gated(d, far, R) == set()
