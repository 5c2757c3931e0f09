"""The OOSM update (fusion/tracker/oosm.py, Bar-Shalom 2002 A1) against independent
references: a hand-written Kalman filter that processes the plots in time order (the
exact posterior for one-step lag), and Monte Carlo consistency (NEES) of the posterior.

The reference model is the continuous white-noise-acceleration CV model (Q = q [[T³/3,
T²/2], [T²/2, T]] per axis): its noise over [t1, t2] is that over [t1, τ] propagated plus
that over [τ, t2], which "processing in time order" presumes. (The product's CV model is
piecewise-constant acceleration, whose noise over a split interval differs slightly, so
the in-order filter itself is a different model there.)"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2
from skyfuse.fusion.tracker.oosm import oosm_update, retrodict
from skyfuse.fusion.tracker.oosm_pass import OutOfSequence
from skyfuse.fusion.tracker.store import Column, ColumnGroup, Table

Q_ACC = 4.0  # m²/s⁴
SIGMA = 50.0  # m, plot σ per axis


def cv_matrices(dt: float) -> tuple[np.ndarray, np.ndarray]:
    """CV F, Q (state x, vx, y, vy; continuous white acceleration per axis)."""
    f = np.array([[1.0, dt], [0.0, 1.0]])
    q = Q_ACC * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    z = np.zeros((2, 2))
    return np.block([[f, z], [z, f]]), np.block([[q, z], [z, q]])


class ContinuousCV:
    """The reference model in the interface ``retrodict`` takes (F(dt), Q(dt) over
    arrays of dt)."""

    def F(self, dt):
        return np.stack([cv_matrices(float(t))[0] for t in np.atleast_1d(dt)])

    def Q(self, dt):
        return np.stack([cv_matrices(float(t))[1] for t in np.atleast_1d(dt)])


H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
R = SIGMA**2 * np.eye(2)


def kf(x, P, dt, z):
    """One predict + update of the reference filter; returns prior and posterior."""
    F, Q = cv_matrices(dt)
    xp, Pp = F @ x, F @ P @ F.T + Q
    S = H @ Pp @ H.T + R
    K = Pp @ H.T @ np.linalg.inv(S)
    return xp, Pp, xp + K @ (z - H @ xp), (np.eye(4) - K @ H) @ Pp


def _late(x, P, xp, Pp, lag, z_tau, model, with_prior=True):
    xs, Ps = x[None], P[None]
    prior = (xp[None], Pp[None]) if with_prior else (None, None)
    x_tau, P_tau, C = retrodict(model, xs, Ps, np.array([lag]), *prior)
    S = H @ P_tau[0] @ H.T + R
    xn, Pn = oosm_update(xs, Ps, C, H, (z_tau - H @ x_tau[0])[None], S[None])
    return xn[0], Pn[0]


@pytest.mark.parametrize("tau", [0.1, 0.55, 0.99])
def test_one_step_lag_equals_in_order_filter(tau):
    """Plots at t = 1, 1+τ, 2: the late plot at 1+τ applied after the one at 2 by the
    OOSM update gives the in-order posterior (A1 is exact for one-step lag)."""
    rng = np.random.default_rng(3)
    model = ContinuousCV()
    x0 = np.array([0.0, 200.0, 0.0, -100.0])
    P0 = np.diag([500.0**2, 50.0**2, 500.0**2, 50.0**2])
    z1, z_tau, z2 = (rng.normal(0, SIGMA, 2) + H @ x0 for _ in range(3))
    _, _, x1, P1 = kf(x0, P0, 1.0, z1)
    # in time order
    _, _, xa, Pa = kf(x1, P1, tau, z_tau)
    _, _, x_ref, P_ref = kf(xa, Pa, 1.0 - tau, z2)
    # z2 first, then z_tau out of sequence
    xp, Pp, x2, P2 = kf(x1, P1, 1.0, z2)
    x_oosm, P_oosm = _late(x2, P2, xp, Pp, 1.0 - tau, z_tau, model)
    np.testing.assert_allclose(x_oosm, x_ref, rtol=0, atol=1e-6 * np.sqrt(np.diag(P_ref)).max())
    np.testing.assert_allclose(P_oosm, P_ref, rtol=1e-7, atol=1e-7 * np.abs(P_ref).max())
    # and it is not the posterior without the late plot
    assert np.linalg.det(P_oosm) < 0.95 * np.linalg.det(P2)


def _nees(model, runs, lag_steps, with_prior, seed=11):
    """NEES of the OOSM posterior at t = 3 s over ``runs`` simulated targets (true CV
    trajectories with the model's own process noise): plots at 1, 2, 3 s and a late plot
    ``lag_steps`` − 1 + 0.4 s before 3 s."""
    rng = np.random.default_rng(seed)
    x0 = np.array([0.0, 200.0, 0.0, -100.0])
    P0 = np.diag([300.0**2, 30.0**2, 300.0**2, 30.0**2])
    tau = 3.0 - (lag_steps - 1) - 0.4
    times = sorted({1.0, 2.0, 3.0, tau})
    out = np.empty(runs)
    for r in range(runs):
        truth, t, plots = rng.multivariate_normal(x0, P0), 0.0, {}
        for tk in times:
            F, Q = cv_matrices(tk - t)
            truth = F @ truth + rng.multivariate_normal(np.zeros(4), Q)
            plots[tk], t = H @ truth + rng.normal(0, SIGMA, 2), tk
        x, P, t = x0, P0, 0.0
        for tk in (1.0, 2.0, 3.0):
            xp, Pp, x, P = kf(x, P, tk - t, plots[tk])
            t = tk
        xn, Pn = _late(x, P, xp, Pp, 3.0 - tau, plots[tau], model, with_prior)
        e = truth - xn
        out[r] = e @ np.linalg.solve(Pn, e)
    return out


@pytest.mark.parametrize(
    "lag_steps,with_prior", [(1, True), (2, True), (1, False)], ids=["A1", "multi-lag", "no-prior"]
)
def test_posterior_covariance_is_consistent(lag_steps, with_prior):
    """Monte Carlo: the mean NEES of the OOSM posterior is within the 99 % interval of
    χ²_4 / runs for exact A1, and not optimistic (≤ the upper bound) for the multi-lag
    and no-prior approximations."""
    model = ContinuousCV()
    runs = 400
    nees = _nees(model, runs, lag_steps, with_prior)
    lo, hi = chi2.ppf([0.005, 0.995], 4 * runs) / runs
    assert nees.mean() <= hi
    if lag_steps == 1 and with_prior:
        assert nees.mean() >= lo


class _Priors:
    """The density's side of the memory: ``track_priors`` hands back what it is given."""

    late_plots = "retrodict"
    mode_dims = (2,)

    def track_priors(self, pred):
        return pred


def test_last_step_memory_follows_the_rows():
    """The out-of-sequence memory (columns of the track store) against a plain dict keyed
    by track id, over random records, new tracks and removals: a row's prior is its own,
    leaves with it, and is used only at the time it was recorded."""
    rng = np.random.default_rng(2)
    tracks = Table(ColumnGroup("tracker", (Column("ids", np.int64), Column("t_last", np.int64))))
    oosm = OutOfSequence(_Priors(), tracks, True)
    ref, next_id = {}, 1
    for step in range(300):
        if rng.random() < 0.3 or not len(tracks):  # some tracks end, new ones start
            if len(tracks):
                tracks.keep(rng.random(len(tracks)) > 0.2)
            tracks.append(ids=next_id + np.arange(2), t_last=np.full(2, -5))
            next_id += 2
        rows = np.sort(rng.choice(len(tracks), size=min(len(tracks), 4), replace=False))
        x = rng.normal(size=(len(rows), 2))
        P = np.einsum("ni,nj->nij", x, x) + np.eye(2)
        tracks.t_last[rows] = step
        oosm.record(rows, np.full(len(tracks), step), ([x], [P]))
        ref.update({int(i): (step, x[k]) for k, i in enumerate(tracks.ids[rows])})
    known, xs, _ = oosm._priors(np.arange(len(tracks)))
    for k, i in enumerate(tracks.ids):
        assert known[k] == (int(i) in ref)
        if known[k]:
            np.testing.assert_array_equal(xs[0][k], ref[int(i)][1])
    tracks.t_last[:1] = 10**6  # a different time: not this track's last step
    assert not oosm._priors(np.arange(1))[0].any()


def test_singular_or_nan_prior_falls_back_without_error():
    """A singular or non-finite stored prior gives the independent-noise retrodiction."""
    model = ContinuousCV()
    x = np.array([[0.0, 100.0, 0.0, 50.0]] * 3)
    P = np.repeat(np.diag([100.0, 10.0, 100.0, 10.0])[None], 3, axis=0)
    Pp = P.copy()
    Pp[0] = 0.0
    Pp[1, 0, 0] = np.nan
    lag = np.full(3, 0.5)
    got = retrodict(model, x, P, lag, x, Pp, np.array([True, True, False]))
    ref = retrodict(model, x, P, lag)
    for a, b in zip(got, ref):
        np.testing.assert_allclose(a, b)
