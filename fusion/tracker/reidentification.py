"""Re-identification of a terminated track by kinematic continuity (docs/reports/tracker-log.md,
"Re-identification").

An aircraft that the radar loses for a while (the cone of silence over the radar,
shadowing, a low aircraft detected intermittently) has its track terminated, and a new
track starts when it is seen again. An operator expects the aircraft to keep its track
number. When a new track is confirmed, it takes over the id of a recently terminated
confirmed track if, and only if, its state is consistent with that track's last fix
predicted to now, and the pairing is unambiguous. Only kinematics decide: Mode-S or
Mode-3/A codes never enter (they only score).

Test, for a terminated track o (last fix x_o, P_o at t_o, the estimate after its last
plot, CV layout [x, vx, y, vy(, z, vz)]) and a newly confirmed track n (x_n, P_n at t_n
≥ t_o, started at or after t_o):

    (R1)  x̂_o = F(Δ) x_o,  P̂_o = F(Δ) P_o F(Δ)ᵀ + Q(Δ),   Δ = t_n − t_o, with the CV
          F and the *continuous* white-noise acceleration Q per axis,
          q̃ [[Δ³/3, Δ²/2], [Δ²/2, Δ]] (Bar-Shalom, Li and Kirubarajan, "Estimation with
          Applications to Tracking and Navigation", 2001, eq. 6.2.2-12; q̃ in m²/s³:
          the quiet straight flight a lost aircraft is assumed to keep; the tracker's
          piecewise-constant Q, q Δ⁴/4, would let one acceleration act for the whole
          gap and grow the gate to kilometres);
    (R1') informative: every per-axis σ of P̂_o's position block ≤ ``max_sigma`` (a
          track whose last fix was a coasting guess, with a velocity σ of hundreds of
          m/s, would otherwise gate anything and continue another aircraft). For the
          same reason a track's fix is replaced at a plot only by a fix at least as
          informative as the old one: both predicted by (R1) to ``FIX_HORIZON`` after
          the plot (the typical gap to bridge), the new one's largest per-axis position
          variance is not larger (:func:`keeps_fix`). A weak plot after a coast, whose
          estimate has a velocity σ of hundreds of m/s, then does not overwrite the
          good fix before it;
    (R1'') moving: both speeds (old fix and new estimate, horizontal) ≥ ``min_speed``.
          Aircraft parked or taxiing on an apron, a few hundred metres apart and nearly
          still, are not told apart by kinematics; re-identifying them joins two
          aircraft (measured on the Barcelona recording);
    (R2)  d² = (x_n − x̂_o)ᵀ (P_n + P̂_o)⁻¹ (x_n − x̂_o) < χ²_{d}(p_reid)   (the track-to-
          track association test of Bar-Shalom, "On the track-to-track correlation
          problem", IEEE TAC 26(2), 1981, eq. 5, with independent errors);
    (R3)  unique: n passes (R2) with exactly one o, and that o with exactly one n of the
          tracks confirmed in the same batch (an ambiguous pair keeps the new id).

A terminated track is a candidate for ``max_gap`` seconds after its last plot; the store
holds at most ``capacity`` tracks (the oldest are dropped first). Times in ns, states in
m and m/s.

Consumers see the ``terminated`` event of the old id when it ends, then a ``confirmed``
event of the same id with the reason ``re-identified (tentative id N)``: an id comes back
only as the continuation of its track, within ``max_gap``, and never while it is alive.
Fresh ids still come from the tracker's counter and are never given twice.

**A live track continued** (``reid_live_gap``). Most splits of a track are not a
termination followed by a new track but a new track started while the old one still
lives and coasts: the plots after a coverage hole, a manoeuvre or an outlier that pulled
the estimate fall outside the old track's gate and start a track of their own, and the
old track only ends seconds after the new one is confirmed (measured on the LEBL
multilateration: the old track's last plot 2 s before the new track's second plot, its
fix then 80-360 m and 6-64 m/s off the new estimate). When a track is confirmed, the
live confirmed tracks o are candidates too, with

    (L1)  no plot of o since n started: o's last plot at or before n's start, and at most
          ``reid_live_gap`` s before the batch (a track that keeps being detected is never
          continued by another, so two aircraft both seen, taxiing in line or side by
          side, keep their ids whatever their kinematics);
    (L2)  (R1)-(R3) with o's last fix, predicted with ``reid_live_q`` instead of ``q``: the
          error of a fix that an outlier pulled or a hole left is a velocity error the
          fix's own covariance does not show, so the quiet-flight q̃ of a terminated
          track would reject the continuation (the nine LEBL continuations had d² of
          13.3-71 ≥ χ²₄(0.99) = 13.28 with q̃ = 4, 1.6-17 with 400); only a new track
          that gates no terminated track is tested against the live ones, (R3) among
          them (the wide live gate is no evidence against a tight terminated match:
          tested jointly, the ambiguity cost four of seven terminated re-identifications
          on a simulated regional run with the GNN tracker);
    (L3)  o's existence ψ below ``reid_live_existence``: the tracker itself doubts the
          old track (the nine LEBL continuations: ψ 0.006-0.05, the track about to end;
          a track of a target in formation that missed a scan or two keeps ψ ≈ 0.6 and
          is not continued by a neighbour's new track: measured on the thesis
          five-target scenario, where without (L3) one such pair was joined).

The pairs are Bar-Shalom's (1981) track-to-track test; ending the continued track when
its successor takes its number is track management in the sense of Blackman and Popoli,
"Design and Analysis of Modern Tracking Systems", Artech House, 1999 (one track number
per target: of two tracks of one target, the redundant one is deleted). In the same
batch, consumers see the ``terminated`` event of the live track (reason ``continued by
tentative id N``), then the ``confirmed`` event of the same id on the new track
(``re-identified (tentative id N)``): an id is alive on one row at a time, and a picture
rebuilt from the events never holds it twice; the track feed sees the id continue (its
row moves to the new track's state). The continuing track adds the old one's scans
with a plot (``updates``) and radar mask to its own, so the plot count of an id never
goes back. Limit: a track whose aircraft stops being detected just as another aircraft
close behind it at the same velocity is first seen (within ``reid_live_gap``, both
faster than ``min_speed``) would be continued by the other's track; the LEBL and
Barcelona recordings have no such case (no identity conflict, no id change added).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from skyfuse.fusion.association.gating import gate_threshold
from skyfuse.fusion.filters.kalman import predict
from skyfuse.fusion.models.cv import ConstantVelocity
from skyfuse.schemas.snapshot import mapping

from .store import Column, ColumnGroup, Table

NS = 1e-9
FIX_HORIZON = 60.0
"""s: the gap over which two fixes of a track are compared (R1') [IMPL]: the gaps to
bridge are 20-60 s for intermittent detection and 80-120 s for the cone of silence."""


def white_noise_acceleration_q(dt: np.ndarray, q: float, ndim: int) -> np.ndarray:
    """(n, 2·ndim, 2·ndim) continuous white-noise acceleration covariance of (R1) for
    dt (n,) s, q̃ in m²/s³, state interleaved [x, vx, y, vy(, z, vz)]."""
    t = np.asarray(dt, dtype=np.float64)
    Q = np.zeros((len(t), 2 * ndim, 2 * ndim))
    for a in range(ndim):
        i = 2 * a
        Q[:, i, i] = q * t**3 / 3.0
        Q[:, i, i + 1] = Q[:, i + 1, i] = q * t**2 / 2.0
        Q[:, i + 1, i + 1] = q * t
    return Q


def _predict_fix(
    x: np.ndarray, P: np.ndarray, dt: np.ndarray, q: float, model: ConstantVelocity
) -> tuple[np.ndarray, np.ndarray]:
    """(R1): fixes x (n, d), P (n, d, d) predicted over dt (n,) s."""
    return predict(x, P, model.F(dt), white_noise_acceleration_q(dt, q, model.ndim))


@numba.njit(cache=True, nogil=True)
def predicted_position_variances(P: np.ndarray, dt: np.ndarray, q: float) -> np.ndarray:
    """(n, ndim) per-axis position variances of (R1)'s P̂ for P (n, d, d) in the CV layout
    [x, vx, y, vy(, z, vz)] predicted over dt (n,) s: the position entry of
    F P Fᵀ + Q per axis, P_pp + 2 Δ P_pv + Δ² P_vv + q̃ Δ³/3 (the closed form of the
    matrix products; the cross-axis terms do not enter a diagonal entry). Compiled: it
    runs for the tracks of every batch (:func:`keeps_fix`)."""
    n, ndim = P.shape[0], P.shape[1] // 2
    out = np.empty((n, ndim))
    for i in range(n):
        t = dt[i]
        for a in range(ndim):
            p, v = 2 * a, 2 * a + 1
            out[i, a] = P[i, p, p] + 2.0 * t * P[i, p, v] + t * t * P[i, v, v] + q * t**3 / 3.0
    return out


@numba.njit(cache=True, nogil=True)
def _keeps_fix(P_old, dt_old, P_new, horizon, q):
    old = predicted_position_variances(P_old, dt_old, q)
    new = predicted_position_variances(P_new, np.full(len(dt_old), horizon), q)
    keep = np.empty(len(dt_old), np.bool_)
    for i in range(len(dt_old)):
        keep[i] = old[i].max() < new[i].max()
    return keep


def keeps_fix(
    P_old: np.ndarray,
    t_old: np.ndarray,
    P_new: np.ndarray,
    t_new: np.ndarray,
    q: float,
) -> np.ndarray:
    """(n,) bool: the old fixes (P_old at t_old ns) predict the position ``FIX_HORIZON``
    after t_new (ns) better than the new estimates P_new at t_new (a smaller largest
    per-axis position variance, both by (R1)), so the old fixes are kept (R1')."""
    if len(P_old) == 0:
        return np.zeros(0, bool)
    dt = np.maximum(t_new - t_old, 0) * NS + FIX_HORIZON
    c = np.ascontiguousarray
    return _keeps_fix(c(P_old, dtype=np.float64), dt.astype(np.float64),
                      c(P_new, dtype=np.float64), FIX_HORIZON, float(q))  # fmt: skip


@numba.njit(cache=True, nogil=True)
def update_fix_columns(hit, t, x, P, fix_x, fix_P, fix_t, horizon, q):
    """:func:`keeps_fix` of the rows ``hit`` against their estimates x, P at ``t``; the
    fix columns take the estimates where the old fix is not kept."""
    n = len(hit)
    dt = np.empty(n)
    d = P.shape[1]
    P_old, P_new = np.empty((n, d, d)), np.empty((n, d, d))
    for i in range(n):
        h = hit[i]
        dt[i] = max(t[i] - fix_t[h], 0) * NS + horizon
        P_old[i] = fix_P[h]
        P_new[i] = P[h]
    keep = _keeps_fix(P_old, dt, P_new, horizon, q)
    for i in range(n):
        if not keep[i]:
            h = hit[i]
            fix_x[h] = x[h]
            fix_P[h] = P[h]
            fix_t[h] = t[i]


def fix_distances(test, x, P, t, xo, Po, to, eligible, q: float | None = None) -> np.ndarray:
    """d² (m, n) of (R2) between new estimates x (m, d), P (m, d, d) at t (m,) ns and the
    fixes xo (n, d), Po (n, d, d) at to (n,) ns predicted by (R1), for the ``eligible``
    (m, n) pairs whose speeds pass (R1'') and whose prediction is informative (R1');
    +inf elsewhere. ``test``: the parameters (``model``, ``q``, ``max_sigma``,
    ``min_speed``), a :class:`TerminatedTracks`; ``q``: another q̃ for (R1)."""
    m, n = len(x), len(xo)
    d2 = np.full((m, n), np.inf)
    if m == 0 or n == 0:
        return d2
    model = test.model
    vel = [i + 1 for i in model.position_index[:2]]
    fast_new = np.hypot(x[:, vel[0]], x[:, vel[1]]) >= test.min_speed
    fast_old = np.hypot(xo[:, vel[0]], xo[:, vel[1]]) >= test.min_speed
    ii, jj = np.nonzero(eligible & fast_new[:, None] & fast_old[None, :])
    if len(ii) == 0:
        return d2
    dt = (t[ii] - to[jj]) * NS
    xp, Pp = _predict_fix(xo[jj], Po[jj], dt, test.q if q is None else q, model)
    pos = list(model.position_index)
    sharp = Pp[:, pos, pos].max(axis=1) <= test.max_sigma**2
    ii, jj, xp, Pp = ii[sharp], jj[sharp], xp[sharp], Pp[sharp]
    dx = x[ii] - xp
    S = P[ii] + Pp
    d2[ii, jj] = np.einsum("pi,pi->p", dx, np.linalg.solve(S, dx[..., None])[..., 0])
    return d2


def unique_pairs(ok: np.ndarray) -> np.ndarray:
    """(R3) over the gated pairs ``ok`` (m, n): for each row, the one column it pairs
    with when that column pairs with no other row, −1 otherwise."""
    out = np.full(ok.shape[0], -1, np.int64)
    unique = (ok.sum(axis=1) == 1)[:, None] & (ok.sum(axis=0) == 1)[None, :] & ok
    rows, cols = np.nonzero(unique)
    out[rows] = cols
    return out


class TerminatedTracks:
    """Bounded store of recently terminated confirmed tracks: a :class:`~.store.Table` of
    their former ids (n,), last fixes x (n, d), P (n, d, d) and fix times t (n,) ns, in
    the order they ended (keyed by the former id, not by a live track: its own table).
    model: the CV output model; the other arguments are (R1)-(R3)'s."""

    def __init__(
        self,
        model: ConstantVelocity,
        max_gap: float,
        q: float = 4.0,
        p_gate: float = 0.99,
        max_sigma: float = 5000.0,
        min_speed: float = 15.0,
        capacity: int = 1024,
    ) -> None:
        self.model, self.max_gap, self.q = model, max_gap, q
        self.max_sigma, self.min_speed, self.capacity = max_sigma, min_speed, capacity
        d = model.dim
        self.gate = gate_threshold(p_gate, d)
        self.rows = Table(
            ColumnGroup(
                "terminated tracks",
                (Column("ids", np.int64, doc="former track id"),
                 Column("x", np.float64, (d,), doc="last fix, CV layout"),
                 Column("P", np.float64, (d, d), doc="its covariance"),
                 Column("t", np.int64, doc="time of the fix, ns")),
            )
        )  # fmt: skip

    def __len__(self) -> int:
        return len(self.rows)

    def add(self, ids: np.ndarray, x: np.ndarray, P: np.ndarray, t: np.ndarray) -> None:
        """Store terminated tracks (their last fixes); keep the newest ``capacity``."""
        if len(ids) == 0:
            return
        self.rows.append(ids=np.asarray(ids, np.int64), x=x, P=P, t=np.asarray(t, np.int64))
        excess = len(self.rows) - self.capacity
        if excess > 0:
            self.rows.keep(np.arange(len(self.rows)) >= excess)

    def expire(self, now_ns: int) -> None:
        """Drop the tracks whose last fix is more than ``max_gap`` s before ``now_ns``."""
        keep = (now_ns - self.rows.t) * NS <= self.max_gap
        if not keep.all():
            self.rows.keep(keep)

    def distances(
        self, x: np.ndarray, P: np.ndarray, t: np.ndarray, born: np.ndarray
    ) -> np.ndarray:
        """d² (m, n) of (R2) between the new tracks' estimates x (m, d), P (m, d, d) at
        times t (m,) ns, started at ``born`` (m,) ns, and the stored tracks predicted by
        (R1); +inf where a new track started before the stored track's last fix."""
        old = self.rows
        eligible = born[:, None] >= old.t[None, :]
        return fix_distances(self, x, P, t, old.x, old.P, old.t, eligible)

    def match(self, x: np.ndarray, P: np.ndarray, t: np.ndarray, born: np.ndarray) -> np.ndarray:
        """For each new track (rows of x), the index of the stored track it continues by
        (R1)-(R3), −1 for none; the matched stored tracks are removed by :meth:`take`."""
        return unique_pairs(self.distances(x, P, t, born) < self.gate)

    def take(self, idx: np.ndarray) -> np.ndarray:
        """The ids of stored tracks ``idx`` (≥ 0), removed from the store."""
        idx = np.asarray(idx, np.int64)
        ids = self.rows.ids[idx]
        keep = np.ones(len(self), bool)
        keep[idx] = False
        self.rows.keep(keep)
        return ids


@dataclass
class Continuations:
    """What :meth:`Reidentification.reidentify` found for the newly confirmed rows (m,):
    ``previous``, the id each had before taking a former track's id (−1: kept its own),
    and ``ended``, the row of the live track it continues and that ends now (−1: none,
    or the track continued had already terminated)."""

    previous: np.ndarray
    ended: np.ndarray


def _first_fix(new) -> dict:
    """A new track's fix: its initial state."""
    return {"fix_x": new.x, "fix_P": new.P, "fix_t": new.t}


class Reidentification:
    """The re-identification part of a tracker: the last informative fix of every live
    track (columns ``fix_x``, ``fix_P``, ``fix_t`` of the track store, (R1')) and the
    terminated tracks awaiting a continuation (:class:`TerminatedTracks`); ``chain``: the
    existence chain, for the existence of the live candidates (L3)."""

    def __init__(self, cfg, model: ConstantVelocity, tracks, density, chain) -> None:
        self.q, self.live_gap, self.live_q = cfg.reid_q, cfg.reid_live_gap, cfg.reid_live_q
        self.live_existence, self.chain = cfg.reid_live_existence, chain
        self.tracks, self.density = tracks, density
        self.terminated = TerminatedTracks(
            model, cfg.reid_max_gap, cfg.reid_q, cfg.reid_p, cfg.reid_max_sigma,
            cfg.reid_min_speed,
        )  # fmt: skip
        d = model.dim
        tracks.declare(
            ColumnGroup(
                "re-identification",
                (Column("fix_x", np.float64, (d,), doc="last informative fix, CV layout"),
                 Column("fix_P", np.float64, (d, d), doc="its covariance"),
                 Column("fix_t", np.int64, doc="its time, ns")),
                init=_first_fix,
            )
        )  # fmt: skip

    def update_fixes(self, hit: np.ndarray, t: np.ndarray) -> None:
        """The fixes of the tracks ``hit`` by a plot at times ``t`` ns: their new
        estimates, unless the old fix stays more informative (R1'); one compiled pass
        writing the fix columns."""
        x, P = self.density.estimates_view()
        tr = self.tracks
        c = np.ascontiguousarray
        update_fix_columns(c(hit, dtype=np.int64), c(t, dtype=np.int64), x, P, tr.fix_x, tr.fix_P,
                      tr.fix_t, FIX_HORIZON, float(self.q))  # fmt: skip

    def ended(self, rows: np.ndarray) -> None:
        """The confirmed tracks ``rows`` end: their fixes become candidates."""
        if len(rows):
            tr = self.tracks
            self.terminated.add(tr.ids[rows], tr.fix_x[rows], tr.fix_P[rows], tr.fix_t[rows])

    def reidentify(self, rows: np.ndarray, t_batch: int) -> Continuations | None:
        """Newly confirmed ``rows`` that continue a recently terminated track ((R1)-(R3)),
        or else a live confirmed track (L1-L3), take its id; None when no track was a
        candidate. The live tracks continued are to end now (:class:`Continuations`)."""
        if len(rows) == 0:
            return None
        self.terminated.expire(t_batch)
        live = self._coasting(rows, t_batch)
        if len(self.terminated) == 0 and len(live) == 0:
            return None
        tr = self.tracks
        x, P = self.density.estimate(rows)
        t, born = tr.t_last[rows], tr.born[rows]
        out = Continuations(np.full(len(rows), -1, np.int64), np.full(len(rows), -1, np.int64))
        gated = self.terminated.distances(x, P, t, born) < self.terminated.gate
        j = unique_pairs(gated)
        dead = j >= 0
        out.previous[dead] = tr.ids[rows[dead]]
        tr.ids[rows[dead]] = self.terminated.take(j[dead])
        free = np.flatnonzero(~gated.any(axis=1))  # (L2): no terminated candidate at all
        if len(live) and len(free):
            d2 = fix_distances(
                self.terminated,
                x[free],
                P[free],
                t[free],
                tr.fix_x[live],
                tr.fix_P[live],
                tr.fix_t[live],
                born[free, None] >= tr.last_update[live][None, :],
                self.live_q,
            )
            k = unique_pairs(d2 < self.terminated.gate)
            hit = free[k >= 0]
            out.ended[hit] = live[k[k >= 0]]
            out.previous[hit] = tr.ids[rows[hit]]
            tr.ids[rows[hit]] = tr.ids[out.ended[hit]]
        return out

    def _coasting(self, rows: np.ndarray, t_batch: int) -> np.ndarray:
        """The live confirmed tracks, other than ``rows``, whose last plot is at most
        ``live_gap`` s before ``t_batch`` (L1) and whose existence is below
        ``live_existence`` (L3); none when ``live_gap`` is None."""
        if self.live_gap is None:
            return np.zeros(0, np.int64)
        tr = self.tracks
        recent = (t_batch - tr.last_update) * NS <= self.live_gap
        recent[rows] = False
        cand = np.flatnonzero(recent & tr.confirmed)
        return cand[self.chain.existence(tr.exist[cand]) < self.live_existence]

    def to_snapshot(self) -> dict:
        """The terminated tracks (the fixes are track-store columns)."""
        return {"terminated": self.terminated.rows.to_snapshot()}

    def from_snapshot(self, snap) -> None:
        self.terminated.rows.from_snapshot(mapping(snap, "re-identification").get("terminated"))
