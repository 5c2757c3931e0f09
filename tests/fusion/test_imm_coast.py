"""IMM long coasts (fusion/tracker/density/imm_mixture.py, step 2): a
prediction over dt > coast_after runs in ⌈dt / coast_step⌉ steps and the turn mode takes
the CV mode's prediction. References: the CV Kalman prediction written out by hand and
the one-step prediction for short dt."""

import numpy as np
import pytest
from skyfuse.fusion.tracker import TrackerConfig
from skyfuse.fusion.tracker.density.imm_mixture import imm_density
from skyfuse.fusion.tracker.store import NewTracks, store_for


def _hand_cv(x, P, dt, q):
    """One CV step per axis, F = [[1, dt], [0, 1]], Q = q [[dt⁴/4, dt³/2], [dt³/2, dt²]]."""
    F = np.kron(np.eye(2), np.array([[1.0, dt], [0.0, 1.0]]))
    Q = np.kron(np.eye(2), q * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]]))
    return F @ x, F @ P @ F.T + Q


def _density(**kw):
    cfg = TrackerConfig(**kw)
    d = imm_density(cfg, "ct")
    x = np.array([[1000.0, 200.0, -3000.0, 50.0]])
    P = np.diag([40.0**2, 6.0**2, 40.0**2, 6.0**2])[None]
    store_for(d).append(NewTracks(x, P))
    return d, x[0], P[0], cfg


def test_long_coast_is_stepped_and_flies_straight():
    d, x, P, cfg = _density(imm_coast_after=30.0, imm_coast_step=10.0)
    pred = d.predict(np.array([0]), np.array([95.0]))
    # CV mode: 10 steps of 9.5 s by hand (the track's mixing keeps the new track's modes)
    mu = pred.comp.mu[0]
    assert mu.sum() == pytest.approx(1.0)
    xc, Pc = pred.comp.x[0][0], pred.comp.P[0][0]
    # a new track: both modes start from the same Gaussian, so mixing returns it unchanged
    xr, Pr = x.copy(), P.copy()
    for _ in range(10):
        xr, Pr = _hand_cv(xr, Pr, 9.5, cfg.imm_q_cv)
    np.testing.assert_allclose(xc, xr, rtol=1e-9)
    np.testing.assert_allclose(Pc, Pr, rtol=1e-7, atol=1e-6)
    # the turn mode flies straight: its position and covariance equal the CV mode's
    ct = d.models[1]
    pos = list(ct.position_index)
    np.testing.assert_allclose(pred.comp.x[1][0][pos], xr[[0, 2]], rtol=1e-9)
    np.testing.assert_allclose(pred.comp.P[1][0][np.ix_(pos, pos)], Pr[np.ix_([0, 2], [0, 2])],
                               rtol=1e-7, atol=1e-6)  # fmt: skip
    # one 95 s step of the CV model would be ≈ 2.3× wider in position
    _, P1 = _hand_cv(x, P, 95.0, cfg.imm_q_cv)
    assert np.sqrt(P1[0, 0] / Pr[0, 0]) > 2.0


def test_short_predictions_are_unchanged():
    d, x, P, cfg = _density(imm_coast_after=30.0)
    d_off, *_ = _density(imm_coast_after=None)
    a = d.predict(np.array([0]), np.array([12.0]))
    b = d_off.predict(np.array([0]), np.array([12.0]))
    for j in range(2):
        np.testing.assert_array_equal(a.comp.x[j], b.comp.x[j])
        np.testing.assert_array_equal(a.comp.P[j], b.comp.P[j])
    xr, Pr = _hand_cv(x, P, 12.0, cfg.imm_q_cv)  # one step, as before
    np.testing.assert_allclose(a.comp.x[0][0], xr, rtol=1e-12)
    np.testing.assert_allclose(a.comp.P[0][0], Pr, rtol=1e-12, atol=1e-9)
    # the turn mode keeps its own (wider) prediction
    assert not np.allclose(a.comp.P[1][0][:2, :2], Pr[np.ix_([0, 2], [0, 2])])
