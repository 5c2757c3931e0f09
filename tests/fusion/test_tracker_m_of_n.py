"""The classical GNN life cycle as a Tracker configuration (``tracker = "gnn"``,
``life_cycle = "m_of_n"``, one-point initiation from the plots no track takes): M-of-N
confirmation and deletion at the scans worked out by hand, a confirmed track ended after
exactly ``max_misses`` empty scans, two targets kept with their ids past a false plot, and
the IMM's per-mode gating keeping a 4 g turn that the mode-mixed gate loses ([MZD] §5)."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig

NS = 10**9
T = 4.0


def _gnn(motion: str = "cv", **kw) -> Tracker:
    settings = {
        "tracker": "gnn", "motion": motion, "life_cycle": "m_of_n", "initiation": "one_point",
        "init_free_weight": 1.0, "reid_max_gap": None, "p_gate": 0.9997, "q": 4.0,
    }  # fmt: skip
    return Tracker(TrackerConfig(**(settings | kw)))


def _batch(k: int, z, sigma: float = 30.0) -> MeasurementBatch:
    z = np.asarray(z, float).reshape(-1, 2)
    R = np.broadcast_to(np.eye(2) * sigma**2, (len(z), 2, 2))
    return MeasurementBatch(int(k * T * NS), "r", z, R, 1.0, 0.0)


def _target(k: int, rng, p0=(0.0, 0.0), v=(200.0, 0.0), sigma=30.0) -> np.ndarray:
    return np.asarray(p0) + np.asarray(v) * T * k + rng.normal(0, sigma, 2)


@pytest.mark.parametrize(
    "m_of_n,seen,confirmed_at,deleted_at",
    [
        ([2, 3], [1, 0, 1, 1, 1], 2, None),  # plots in scans 0 and 2: 2 of the first 3
        ([2, 3], [1, 0, 0, 1, 1], None, 2),  # 1 of 3 after scan 2: can no longer reach 2
        ([3, 4], [1, 1, 0, 1, 1], 3, None),
        ([3, 4], [1, 0, 0, 1, 1], None, 2),  # 1 + one scan left < 3 already at scan 2
        # 1 of 1 at birth: confirmed by the next scan's management (which precedes the
        # initiation of a scan), then 3 misses end it
        ([1, 1], [1, 0, 0, 0, 0], 1, 3),
    ],
)
def test_m_of_n_confirms_and_deletes_at_the_scans_worked_out_by_hand(
    m_of_n, seen, confirmed_at, deleted_at
):
    rng = np.random.default_rng(0)
    trk = _gnn(confirm_m_of_n=m_of_n)
    got_confirmed, got_deleted = None, None
    for k, s in enumerate(seen):
        out = trk.step(_batch(k, _target(k, rng) if s else np.zeros((0, 2))))
        first = out.ids == 1  # the track the plot of scan 0 started
        if got_confirmed is None and out.confirmed[first].any():
            got_confirmed = k
        if got_deleted is None and not first.any():
            got_deleted = k
    assert (got_confirmed, got_deleted) == (confirmed_at, deleted_at)


def test_a_confirmed_track_ends_after_exactly_max_misses_empty_scans():
    rng = np.random.default_rng(1)
    trk = _gnn(max_misses=4)
    for k in range(5):
        out = trk.step(_batch(k, _target(k, rng)))
    assert out.confirmed.tolist() == [True]
    for k in range(5, 12):
        out = trk.step(_batch(k, np.zeros((0, 2))))
        if len(out) == 0:
            break
    assert k == 5 + 4 - 1  # the 4th empty scan ends it
    assert [e.kind for e in out.events] == ["terminated"]
    assert out.events[0].reason == "max_misses scans without a plot"


@pytest.mark.parametrize("motion", ["cv", "imm-pcwpa", "singer"])
def test_two_targets_keep_their_ids_and_a_false_plot_starts_a_track_that_dies(motion):
    rng = np.random.default_rng(0)
    trk = _gnn(motion, imm_mu0=[0.5, 0.5], imm_tpm=[0.95, 0.05, 0.1, 0.9], imm_tpm_period=T)
    targets = [((0.0, 0.0), (200.0, 0.0)), ((0.0, 3000.0), (200.0, -20.0))]
    ids = []
    for k in range(12):
        z = [_target(k, rng, p0, v) for p0, v in targets]
        if k == 5:
            z.append(np.array([-40_000.0, 40_000.0]))
        out = trk.step(_batch(k, z))
        ids.append(out.ids.tolist())
    # the false plot's track (id 3, born at scan 5) has 1 plot in 3 scans at scan 7
    assert ids[5] == ids[6] == [1, 2, 3] and ids[7] == [1, 2] and ids[-1] == [1, 2]
    assert out.confirmed.all()
    truth = np.array([np.asarray(p0) + np.asarray(v) * 44.0 for p0, v in targets])
    pos = out.states[:, [0, 2]]
    assert np.abs(pos - truth).max() < 150


def test_per_mode_imm_gating_keeps_a_4g_turning_target_the_mixed_gate_loses():
    """[MZD] §5 gates per model: the sharp mode's wider gate keeps the track through a
    4 g turn (T = 4 s, 300 m/s, 100 m noise); the mode-mixed gate loses it more often."""
    g, v = 9.80665, 300.0
    pos, vel = np.array([0.0, 0.0]), np.array([v, 0.0])
    truth = []
    for k in range(16):
        for _ in range(400):
            if 7 <= k < 9:
                vel = vel + 4 * g * np.array([-vel[1], vel[0]]) / v * 0.01
            pos = pos + vel * 0.01
        truth.append(pos.copy())
    kept = {}
    for gating in ("per-mode", "mixed"):
        kept[gating] = 0
        for seed in range(6):
            rng = np.random.default_rng(seed)
            trk = _gnn(
                "imm-pcwpa", imm_gating=gating, imm_tpm=[0.95, 0.05, 0.1, 0.9],
                imm_mu0=[0.5, 0.5], imm_tpm_period=T, v_max=350.0 * np.sqrt(3.0),
            )  # fmt: skip
            for k, p in enumerate(truth):
                out = trk.step(_batch(k, p + rng.normal(0, 100.0, 2), sigma=100.0))
            kept[gating] += out.ids.tolist() == [1]
    assert kept["per-mode"] >= 5
    assert kept["mixed"] < kept["per-mode"]
