"""A new density is one module plus one registration; every density's tracker snapshot
restores to the same tracker.

``KalmanDensity`` below is written here against the density protocol
(``fusion/tracker/density/base.py``) only: one Gaussian per track, constant velocity, the
PDA update, and the out-of-sequence update through ``fusion.tracker.oosm``. Registered as
a motion (``register_motion``), it runs through the tracker with no other change
anywhere (its track-store columns, the out-of-sequence pass, the snapshot and the
kernel warm-up all go through the protocol). Reference: the shipped IPDA with the
constant-velocity Gaussian mixture (depth 0: one Gaussian per track, the same
mathematics written another way), which must give the same tracks, ids, events and
states (to rounding) on a scene with clutter, births, a death and a radar whose batches
arrive one scan late.

Snapshots: a tracker of every shipped density (Gaussian mixture with and without Singer
memory, both IMMs, particles) and of the test density, stopped half-way through the
scene and restored from its snapshot (:func:`tracker_from_snapshot`), goes on exactly as
the tracker that never stopped (every output bitwise: ids, states, existence, events).
Snapshots of another version or configuration, or whose columns do not fit their
declarations, are refused with a message naming what is wrong.
"""

from __future__ import annotations

import copy
import pickle
from dataclasses import dataclass

import numpy as np
import pytest
from skyfuse.fusion.association.gating import GatedPairs, gate, gate_probability
from skyfuse.fusion.filters.kalman import update_with_innovation
from skyfuse.fusion.models.cv import ConstantVelocity
from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig
from skyfuse.fusion.tracker.density.base import GatedTable, Prediction, Retrodiction, TrackDensity
from skyfuse.fusion.tracker.kernel_warmup import warm_up
from skyfuse.fusion.tracker.oosm import oosm_update, retrodict
from skyfuse.fusion.tracker.registry import MOTIONS, register_motion
from skyfuse.fusion.tracker.store import Column, ColumnGroup
from skyfuse.fusion.tracker.tracker import tracker_from_snapshot
from skyfuse.schemas.snapshot import SnapshotError

NS = 10**9


# ----------------------------------------------------------------------- the density
@dataclass
class KalmanPrediction(Prediction):
    """Predicted (or, late, retrodicted) Gaussians: x (s, d), P (s, d, d); for a late
    update also the cross terms C of the retrodiction."""

    x: np.ndarray | None = None
    P: np.ndarray | None = None
    C: np.ndarray | None = None


@dataclass
class KalmanTable(GatedTable):
    pairs: GatedPairs | None = None
    R: np.ndarray | None = None


class KalmanDensity:
    """One Gaussian per track (CV): x, P columns; PDA update ([thesis] (2.37))."""

    late_plots = "retrodict"

    def __init__(self, model: ConstantVelocity) -> None:
        self.model, self.dim = model, model.dim
        self.mode_dims = (model.dim,)
        self.H = model.H()
        self.pos = np.array(model.position_index)
        self.stats: dict[str, int] = {}
        self.tracks = None

    def attach(self, tracks) -> None:
        d = self.dim
        columns = (Column("x", np.float64, (d,)), Column("P", np.float64, (d, d)))
        tracks.declare(ColumnGroup("kalman", columns, init=lambda n: {"x": n.x, "P": n.P}))
        self.tracks = tracks

    def predict(self, rows, dt) -> KalmanPrediction:
        x, P = self.model.predict(self.tracks.x[rows], self.tracks.P[rows], np.asarray(dt))
        return self._prediction(rows, x, P)

    def _prediction(self, rows, x, P, C=None) -> KalmanPrediction:
        p = self.pos
        return KalmanPrediction(rows, x[:, p], P[:, p][:, :, p], x, P, C)

    def likelihoods(self, pred, z, R, g) -> KalmanTable:
        pairs = gate(pred.z_mean, pred.S0, z, R, g)
        p = np.exp(pairs.log_pdf) / gate_probability(g, z.shape[1])
        return KalmanTable(pairs.state, pairs.plot, p, pairs, np.broadcast_to(R, (len(z), 2, 2)))

    def _merge(self, rows, x0, P0, beta0, table, beta, x_pairs, P_pairs) -> None:
        """PDA: x = β₀ x⁰ + Σ β_i x^i, P = Σ β (P + (x − x̂)(x − x̂)ᵀ) per track."""
        n = len(rows)
        w = np.concatenate([beta0, beta])
        grp = np.concatenate([np.arange(n), table.tp_track])
        xs, Ps = np.concatenate([x0, x_pairs]), np.concatenate([P0, P_pairs])
        W = np.bincount(grp, weights=w, minlength=n)
        x = np.zeros((n, self.dim))
        np.add.at(x, grp, w[:, None] * xs)
        x /= W[:, None]
        dx = xs - x[grp]
        P = np.zeros((n, self.dim, self.dim))
        np.add.at(P, grp, w[:, None, None] * (Ps + dx[:, :, None] * dx[:, None, :]))
        self.tracks.x[rows], self.tracks.P[rows] = (
            x,
            0.5 * (P + P.swapaxes(1, 2)) / W[:, None, None],
        )

    def update(self, pred, table, beta0, beta) -> None:
        pr = table.pairs
        x, P = update_with_innovation(
            pred.x[pr.state], pred.P[pr.state], self.H, pr.S, pr.nu, table.R[pr.plot]
        )
        self._merge(pred.rows, pred.x, pred.P, beta0, table, beta, x, P)

    def estimate(self, rows):
        return self.tracks.x[rows].copy(), self.tracks.P[rows].copy()

    def estimates_view(self):
        return self.tracks.x, self.tracks.P

    def component_counts(self):
        return np.ones(len(self.tracks), np.int64)

    # the out-of-sequence update (Bar-Shalom 2002 A1, fusion/tracker/oosm.py)
    def track_priors(self, pred):
        return [pred.x], [pred.P]

    def retrodict(self, rows, lag, priors) -> KalmanPrediction:
        known, xp, Pp = priors
        x, P = self.tracks.x[rows], self.tracks.P[rows]
        x_tau, P_tau, C = retrodict(self.model, x, P, lag, xp[0], Pp[0], known)
        p = self.pos
        return KalmanPrediction(rows, x_tau[:, p], P_tau[:, p][:, :, p], x, P, C)

    def update_late(self, pred, table, beta0, beta) -> None:
        pr = table.pairs
        x, P = oosm_update(pred.x[pr.state], pred.P[pr.state], pred.C[pr.state], self.H,
                           pr.nu, pr.S)  # fmt: skip
        self._merge(pred.rows, pred.x, pred.P, beta0, table, beta, x, P)

    def to_snapshot(self) -> dict:
        return {}  # everything is in the track store's columns

    def from_snapshot(self, snap) -> None:
        if snap != {}:
            raise SnapshotError("the Kalman density has no state of its own")


@pytest.fixture
def kalman_motion():
    """The one registration of the test density (removed afterwards)."""
    register_motion(
        "test-kalman", lambda cfg: KalmanDensity(ConstantVelocity(q=cfg.q)), "one Gaussian (test)"
    )
    yield "test-kalman"
    MOTIONS.pop("test-kalman")


# ----------------------------------------------------------------------- the scene
def scene(seed: int = 3, scans: int = 30) -> list[MeasurementBatch]:
    """Six targets at 150-250 m/s, one of which stops at scan 15; radar A at 4k s and
    radar B at 4k + 2 s (P_D 0.9, σ 60 m, 4 clutter plots per batch over 20 × 20 km), B's
    batch of 4k + 2 arriving after A's of 4k + 4 (late: the out-of-sequence update)."""
    rng = np.random.default_rng(seed)
    p0 = rng.uniform(-6e3, 6e3, (6, 2))
    v = rng.uniform(150.0, 250.0, 6)[:, None] * np.stack([np.cos(h := rng.uniform(0, 6.3, 6)),
                                                          np.sin(h)], 1)  # fmt: skip
    area, R = 20e3**2, 60.0**2 * np.eye(2)

    def batch(t: float, radar: str) -> MeasurementBatch:
        alive = np.arange(6) if t < 60.0 else np.arange(5)
        z = p0[alive] + v[alive] * t + rng.normal(0, 60.0, (len(alive), 2))
        z = z[rng.random(len(z)) < 0.9]
        clutter = rng.uniform(-10e3, 10e3, (rng.poisson(4), 2))
        zs = np.vstack([z, clutter])
        return MeasurementBatch(round(t * NS), radar, zs, R, 0.9, 4 / area)

    out = []
    for k in range(1, scans):
        out.append(batch(4.0 * k, "A"))
        if k > 1:
            out.append(batch(4.0 * (k - 1) + 2.0, "B"))
    return out


def _config(**kw) -> TrackerConfig:
    return TrackerConfig(q=4.0, v_max=400.0, init_max_dt=9.0, **kw)


def _same(a, b) -> None:
    """Two tracker outputs bitwise equal (ids, states, existence, statuses, events)."""
    np.testing.assert_array_equal(a.ids, b.ids)
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.covariances, b.covariances)
    np.testing.assert_array_equal(a.existence, b.existence)
    np.testing.assert_array_equal(a.confirmed, b.confirmed)
    assert [(e.kind, e.track_id) for e in a.events] == [(e.kind, e.track_id) for e in b.events]


# ----------------------------------------------------------------------- the tests
def test_a_density_of_this_module_runs_through_the_tracker_like_the_shipped_one(kalman_motion):
    cfg = _config(tracker="ipda", motion=kalman_motion)
    tr, ref = Tracker(cfg), Tracker(_config(tracker="ipda", motion="cv"))
    assert isinstance(tr.density, KalmanDensity) and isinstance(tr.density, TrackDensity)
    assert isinstance(tr.density, Retrodiction) and tr.oosm.enabled
    events = []
    for b in scene():
        a, c = tr.step(b), ref.step(b)
        np.testing.assert_array_equal(a.ids, c.ids)
        np.testing.assert_array_equal(a.confirmed, c.confirmed)
        np.testing.assert_allclose(a.states, c.states, rtol=1e-9, atol=1e-6)
        np.testing.assert_allclose(a.existence, c.existence, rtol=1e-9, atol=1e-12)
        assert [(e.kind, e.track_id) for e in a.events] == [(e.kind, e.track_id) for e in c.events]
        events += [e.kind for e in a.events]
    assert tr.totals["oosm_tracks"] > 20 and tr.totals["oosm_prior_known"] > 20
    assert tr.totals["oosm_hits"] > 10
    assert events.count("confirmed") >= 6 and "terminated" in events
    assert warm_up() >= 0.0  # the registry's warm-up walks the new density too (it has none)


CONFIGS = [
    ("ipda", "cv", {}),
    ("lmits", "cv", {"depth": 2}),
    ("jits", "imm-cv-ct", {"depth": 1}),
    ("gnn", "imm-cv-singer", {}),
    ("lmits", "imm-surface", {"depth": 1}),
    ("lmipf", "cv", {"particles": 64}),
    ("ipda", "test-kalman", {}),
]


@pytest.mark.parametrize("kind, motion, extra", CONFIGS)
def test_a_restored_tracker_goes_on_as_the_one_that_never_stopped(
    kind, motion, extra, kalman_motion
):
    batches = scene(seed=4)
    ref = Tracker(_config(tracker=kind, motion=motion, **extra))
    half = len(batches) // 2
    for b in batches[:half]:
        ref.step(b)
    assert ref.tracks.confirmed.sum() >= 3
    snap = copy.deepcopy(ref.to_snapshot())  # nothing shared with the running tracker
    again = tracker_from_snapshot(snap)
    np.testing.assert_array_equal(again.ids, ref.ids)
    assert again.tracks.names == ref.tracks.names
    pickled = pickle.loads(pickle.dumps(ref)) if motion != "test-kalman" else None
    for b in batches[half:]:
        out = ref.step(b)
        _same(again.step(b), out)
        if pickled is not None:  # the Monte Carlo workers receive pickled trackers
            _same(pickled.step(b), out)


def test_snapshots_that_do_not_fit_are_refused_with_a_reason():
    tr = Tracker(_config(tracker="lmits", motion="imm-cv-ct"))
    for b in scene()[:20]:
        tr.step(b)
    snap = tr.to_snapshot()
    n = len(tr.ids)

    def refused(edit, match):
        s = copy.deepcopy(snap)
        edit(s)
        with pytest.raises(SnapshotError, match=match):
            tracker_from_snapshot(s)

    refused(
        lambda s: s.update(version=0),
        f"version 0: this version of skyfuse reads version {Tracker.SNAPSHOT_VERSION}",
    )
    with pytest.raises(SnapshotError, match="configuration differs"):  # into another tracker
        Tracker(_config(tracker="lmits", motion="imm-cv-ct", depth=2)).from_snapshot(snap)
    refused(lambda s: s["config"].update(depth=-1), "tracker configuration")
    cols = lambda s: s["tracks"]["columns"]  # noqa: E731
    refused(lambda s: cols(s).update(exist=np.zeros((n + 1, 2))), r"exist: shape \(")
    refused(lambda s: cols(s).update(ids=cols(s)["ids"].astype(np.int32)), "ids: dtype int32")
    refused(lambda s: cols(s).pop("reach_since"), "reach_since: NoneType")
    refused(lambda s: cols(s).update(extra=np.zeros(n)), "undeclared column 'extra'")
    refused(lambda s: cols(s)["ids"].__setitem__(0, cols(s)["ids"][1]), "track ids not unique")
    comp = lambda s: s["density"]["components"]["columns"]  # noqa: E731
    refused(lambda s: comp(s)["track"].__setitem__(0, n), "track rows")
    refused(lambda s: s.update(radar_names=["A"]), "radar masks beyond")
