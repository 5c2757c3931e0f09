"""JIPDA ([thesis] §6.2.1) against a brute-force enumeration of joint events written here."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig
from skyfuse.fusion.tracker.jits import event_count, feasible_events

T = 1.0
QT = 0.75 * np.array([[0.25, 0.5], [0.5, 1.0]])
F = np.kron(np.eye(2), np.array([[1.0, T], [0.0, 1.0]]))
Q = np.kron(np.eye(2), QT)
H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
R = 25.0 * np.eye(2)
G = -2.0 * math.log(0.01)
PG = 0.99
PD, RHO, D11 = 0.85, 2e-4, 0.98


def brute_force_jipda(tracks, plots):
    """tracks: list of (x, P, ψ). Returns per track (ψ_post, x, P) from (6.2-6.8)."""
    preds = []
    for x, P, psi in tracks:
        xp, Pp = F @ x, F @ P @ F.T + Q
        S = H @ Pp @ H.T + R
        Si = np.linalg.inv(S)
        lik = {}
        for i, z in enumerate(plots):
            nu = z - H @ xp
            d2 = nu @ Si @ nu
            if d2 < G:
                lik[i] = math.exp(-0.5 * d2) / (2 * math.pi * math.sqrt(np.linalg.det(S))) / PG
        preds.append((xp, Pp, S, D11 * psi, lik))
    options = [[None, *sorted(p[4])] for p in preds]
    events, weights = [], []
    for e in itertools.product(*options):
        used = [i for i in e if i is not None]
        if len(used) != len(set(used)):
            continue  # a plot to two tracks is infeasible
        w = 1.0
        for (_, _, _, psi, lik), i in zip(preds, e):
            w *= (1 - PD * PG * psi) if i is None else PD * PG * psi * lik[i] / RHO
        events.append(e)
        weights.append(w)
    c = sum(weights)
    out = []
    for t, (xp, Pp, S, psi, lik) in enumerate(preds):
        p0 = sum(w for e, w in zip(events, weights) if e[t] is None) / c
        joint = {0: p0 * (1 - PD * PG) * psi / (1 - PD * PG * psi)}
        for i in lik:
            joint[i + 1] = sum(w for e, w in zip(events, weights) if e[t] == i) / c
        psi_post = sum(joint.values())
        K = Pp @ H.T @ np.linalg.inv(S)
        A = np.eye(4) - K @ H
        xs = {0: xp}
        Ps = {0: Pp}
        for i in lik:
            xs[i + 1] = xp + K @ (plots[i] - H @ xp)
            Ps[i + 1] = A @ Pp @ A.T + K @ R @ K.T
        beta = {k: v / psi_post for k, v in joint.items()}
        xm = sum(beta[k] * xs[k] for k in beta)
        Pm = sum(beta[k] * (Ps[k] + np.outer(xs[k] - xm, xs[k] - xm)) for k in beta)
        out.append((psi_post, xm, Pm))
    return out, len(events)


P0 = np.diag([30.0, 20.0, 30.0, 20.0])
TRACKS = [
    (np.array([0.0, 10.0, 0.0, 0.0]), P0, 0.7),
    (np.array([25.0, 10.0, 5.0, 0.0]), P0, 0.4),
]
PLOTS = np.array([[12.0, 1.0], [22.0, 4.0], [30.0, 6.0], [17.0, -3.0], [45.0, 2.0]])


def run_tracker(kind, cap=5000):
    cfg = TrackerConfig(
        motion="cv", tracker=kind, q=0.75, initiation="none", clutter="known", jipda_max_events=cap
    )
    tr = Tracker(cfg)
    ids = [tr.add_track(x, P, 0, existence=psi) for x, P, psi in TRACKS]
    out = tr.step(MeasurementBatch(10**9, "r", PLOTS, R, PD, RHO))
    return [list(out.ids).index(i) for i in ids], out


def test_jipda_two_tracks_sharing_plots_equals_brute_force():
    ref, n_events = brute_force_jipda(TRACKS, PLOTS)
    rows, out = run_tracker("jipda")
    assert out.stats["clusters"] == 1 and out.stats["events"] == n_events
    assert n_events > 6  # the tracks really share several plots
    for r, (psi, x, P) in zip(rows, ref):
        assert out.existence[r] == pytest.approx(psi, rel=1e-9)
        np.testing.assert_allclose(out.states[r], x, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(out.covariances[r], P, rtol=1e-8, atol=1e-8)


def test_jipda_differs_from_independent_ipda_when_sharing():
    ref, _ = brute_force_jipda(TRACKS, PLOTS)
    rows, out = run_tracker("ipda")
    assert abs(out.existence[rows[1]] - ref[1][0]) > 1e-3


def test_event_cap_falls_back_to_lm_and_counts_it():
    _, out = run_tracker("jipda", cap=3)
    assert out.stats["lm_fallback"] == 1
    _, lm = run_tracker("lmipda")
    np.testing.assert_allclose(out.existence, lm.existence)
    np.testing.assert_allclose(out.states, lm.states)


@pytest.mark.parametrize(("n", "m", "count"), [(5, 5, 1546), (5, 10, 63591), (1, 3, 4)])
def test_event_count_formula(n, m, count):
    assert event_count(n, m) == count  # [thesis] (6.9)-(6.10) examples


@pytest.mark.parametrize(("n", "m"), [(2, 3), (3, 3), (3, 4)])
def test_feasible_events_match_itertools_when_all_gated(n, m):
    opts = [np.arange(a * m, (a + 1) * m) for a in range(n)]  # table rows of track a
    plots = [np.arange(m) for _ in range(n)]
    ev = feasible_events(opts, plots, 10**6)
    brute = [
        e
        for e in itertools.product(*[[None, *range(m)] for _ in range(n)])
        if len([i for i in e if i is not None]) == len({i for i in e if i is not None})
    ]
    assert len(ev) == len(brute) == event_count(n, m)
    got = {tuple(None if v < 0 else int(v) % m for v in row) for row in ev}
    assert got == set(brute)
    assert feasible_events(opts, plots, len(brute) - 1) is None
