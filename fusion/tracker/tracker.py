"""The existence-based multi-target tracker: a short sequence of swappable parts
([thesis] ch. 5-7; docs/concepts/tracker-parts.md).

``Tracker(config).step(batch) -> TrackerOutput`` applies one :class:`MeasurementBatch`
(one radar sector or scan, system frame) to all tracks. Per batch:

1. **Coverage** (:mod:`.coverage`, multi-radar): only tracks the batch could have seen
   are predicted to their illumination time and updated; the others keep their state
   and existence (a radar that does not see a region does not erode its tracks). A
   report-based sensor's P_D applies only to the tracks it reported within its
   ``report_timeout`` (:mod:`.report_clock`): its silence about the others is no miss.
2. **Prediction** of the track density (:mod:`.density`: Gaussian mixture with Singer
   memory, [thesis] 5.4-5.5, or an IMM per component; particle clouds for ipf/lmipf,
   [LM-IPF] eq. 6) and of existence (Markov chain, :mod:`.existence`, [thesis] 5.3) over
   per-track dt arrays.
3. **Likelihoods**: the density gates the plots and returns the track × plot table
   p^τ_i = likelihood / P_G ([thesis] 5.7-5.10, 4.17).
4. **Clutter** density per table row (:mod:`.clutter`): known or estimated (2.35).
5. **Association** part from the registry (:mod:`.registry`, :mod:`.associators`):
   single (IPDA/ITS, 5.16-5.18), lm (6.12-6.22), joint (6.1-6.8), gnn (MAP event).
6. **Update** of the density with β₀, β (ITS children 5.12-5.15, merge, pruning); the
   tracks whose illumination time is older than their state take the out-of-sequence
   update instead (:mod:`.oosm_pass`).
7. **Management** (:mod:`.management`): duplicate removal, confirmation, termination
   ([thesis] §7.1-7.2); **initiation** (:mod:`.initiation`) from the plots no track
   gated.

The state of every track is one row of the track store ``Tracker.tracks``
(:mod:`.store`): columns declared by their owners (the tracker, the density, the
out-of-sequence memory, the re-identification). The steps shared with the
out-of-sequence pass are :class:`~.phases.Phases`. ``to_snapshot`` /
``from_snapshot`` write and read the whole state by those declarations, with a version
and the configuration.

All arrays run over tracks, components and plots; the only Python loops are over JIPDA
clusters with more than one track and GNN clusters.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from skyfuse.fusion.association.gating import gate_probability, gate_threshold
from skyfuse.fusion.models.cv import ConstantVelocity
from skyfuse.schemas.snapshot import SnapshotError, check_version, counts, entry, strings

from .config import TrackerConfig
from .coverage import detection_share, existence_clock, select_tracks, track_heights
from .density.base import TrackDensity
from .events import TrackEventRecord
from .existence import ExistenceChain, markov_chain_one, markov_chain_two
from .identity import Identity, TrackIdentity
from .initiation import PlotBuffer, one_point, pair_plots, two_point
from .management import (
    duplicates,
    life_cycle_columns,
    shared_plot_pairs,
    to_confirm,
    to_confirm_m_of_n,
    to_terminate,
    to_terminate_by_count,
)
from .measurements import MeasurementBatch
from .oosm_pass import OutOfSequence
from .phases import Phases
from .registry import ASSOCIATIONS, make_density
from .reidentification import Reidentification
from .report_clock import ReportClock
from .store import Column, ColumnGroup, NewTracks, Table

NS = 1e-9
#: Tracks whose closed-form predicted existence is at least τ_t + this are not terminated
#: without the exact chain prediction (the two differ by rounding, ~1e-15).
TERMINATION_MARGIN = 1e-6


@dataclass
class OutputPrediction:
    """The track estimates x (n, d), P (n, d, d) and existence-chain states (n, 2) at
    their times ``t_last`` (n,) ns after one step (copies), predicted on demand to
    ``time_ns`` with the output model (CV, [thesis] 5.4) and the existence chain (5.3):
    only the rows a consumer asks for are predicted."""

    time_ns: int
    x: np.ndarray
    P: np.ndarray
    t_last: np.ndarray
    exist: np.ndarray
    model: ConstantVelocity
    chain: ExistenceChain
    t_exist: np.ndarray | None = None  # existence clocks (n,) ns; None: t_last

    def rows(self, idx: np.ndarray | slice) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, P, ψ) of the rows ``idx`` predicted to ``time_ns`` (not stored)."""
        x, P = self.x[idx], self.P[idx]
        if len(x) == 0:
            return x, P, np.zeros(0)
        dt = np.maximum(self.time_ns - self.t_last[idx], 0) * NS
        x, P = self.model.predict(x, P, dt)
        te = self.t_last if self.t_exist is None else self.t_exist
        dt_e = np.maximum(self.time_ns - te[idx], 0) * NS
        psi = self.chain.existence(self.chain.predict(self.exist[idx], dt_e))
        return x, P, psi


@dataclass
class TrackerOutput:
    """All live tracks after one batch, predicted to ``time_ns`` (arrays over tracks).

    ids (n,), states (n, d), covariances (n, d, d), existence (n,), confirmed (n,) bool,
    updates (n,) scans with a plot, radar_mask (n,) bit i = ``radar_names[i]`` updated the
    track, last_update_ns (n,), assigned_plot (n,) index of the most likely plot of this
    batch for the track (−1: none or not in coverage), events, stats, the validated
    batch (its ``target_ids`` serve evaluation) and the tracks' identity (copies,
    :class:`~.identity.TrackIdentity`; None when the tracker does not attribute it).

    ``states``, ``covariances`` and ``existence`` are predicted from ``prediction`` on
    first access (all rows at once); :meth:`predicted` predicts only some rows (the
    feed's changed tracks, the registration's assigned tracks), so a batch that changes
    few of many tracks does not predict them all."""

    time_ns: int
    radar_id: str
    ids: np.ndarray
    prediction: OutputPrediction
    confirmed: np.ndarray
    updates: np.ndarray
    radar_mask: np.ndarray
    radar_names: list[str]
    last_update_ns: np.ndarray
    assigned_plot: np.ndarray
    events: list[TrackEventRecord] = field(default_factory=list)
    stats: dict[str, int] = field(default_factory=dict)
    batch: MeasurementBatch | None = None
    identity: TrackIdentity | None = None
    _all: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return len(self.ids)

    def _predicted_all(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self._all is None:
            self._all = self.prediction.rows(slice(None))
        return self._all

    @property
    def states(self) -> np.ndarray:
        return self._predicted_all()[0]

    @property
    def covariances(self) -> np.ndarray:
        return self._predicted_all()[1]

    @property
    def existence(self) -> np.ndarray:
        return self._predicted_all()[2]

    def predicted(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(states, covariances, existence) of ``rows`` only, at ``time_ns``."""
        if self._all is not None:
            return tuple(a[rows] for a in self._all)
        return self.prediction.rows(np.asarray(rows, dtype=np.int64))

    def radars_of(self, i: int) -> list[str]:
        m = int(self.radar_mask[i])
        return [name for b, name in enumerate(self.radar_names) if m >> b & 1]


class Tracker:
    """Multi-target tracker over arrays; see the module docstring for one step.

    Every piece of per-track state is a column of the track store ``tracks``
    (:mod:`.store`), declared by its owner: the tracker's own (``ids``, ``exist`` (n, 2)
    Markov-chain state, ``t_last`` ns, ``confirmed``, ``updates``, ``radar_mask``,
    ``last_update`` ns, ``height`` m of the last plot (NaN unknown), ``coast_from`` ns (the
    last plot or the last batch that found the track in a cone of silence; ``max_coast``
    counts from it), ``born`` ns), the density's, the out-of-sequence memory and the
    re-identification fixes. ``density``: a :class:`~.density.base.TrackDensity` not yet
    attached to a store (default: the configured one, :func:`.registry.make_density`)."""

    SNAPSHOT_VERSION = 3
    """Version of :meth:`to_snapshot` (the columns and parts it holds): 2 adds the
    identity part's columns and its configuration; 3 the report clock (:mod:`.report_clock`)."""

    def __init__(self, config: TrackerConfig | None = None, density=None) -> None:
        self.cfg = cfg = config or TrackerConfig()
        # output model: predicts the CV-layout estimates between batches ([thesis] 5.4)
        self.model = ConstantVelocity(q=cfg.q, ndim=cfg.ndim, q_vertical=cfg.q_vertical)
        self.d = self.model.dim
        self.k = cfg.ndim
        self.pos = np.array(self.model.position_index)
        self.vel = self.pos + 1
        self.g = gate_threshold(cfg.p_gate, self.k)
        self.P_G = gate_probability(self.g, self.k)
        self.g_dup = gate_threshold(cfg.duplicate_p, self.d)
        self.chain = self._make_chain(cfg)
        self.tracks = Table(self._columns())
        if cfg.life_cycle == "m_of_n":
            self.tracks.declare(life_cycle_columns())
        self.density: TrackDensity = make_density(cfg) if density is None else density
        self.density.attach(self.tracks)
        self.reid = (
            None
            if cfg.reid_max_gap is None
            else Reidentification(cfg, self.model, self.tracks, self.density, self.chain)
        )
        self.oosm = OutOfSequence(self.density, self.tracks, cfg.oosm)
        self.identity = Identity(cfg, self.tracks, self.chain) if cfg.identity else None
        self.reports = ReportClock(self.tracks, cfg.report_sensors)
        self.associate = ASSOCIATIONS[cfg.association]
        self.phases = Phases(cfg, self.tracks, self.chain, self.associate, self.g, self.P_G,
                             self.reid, self.identity)  # fmt: skip
        self.newest_ns = 0
        """The newest batch time applied, ns: outputs never go back in time."""
        self.buffer = PlotBuffer.empty(self.k)
        self.radar_names: list[str] = []
        self._next_id = 1
        self._next_uid = 1
        self.totals: dict[str, int] = {}

    def _columns(self) -> ColumnGroup:
        """The tracker's own columns (:meth:`_new_rows` fills those without a fill)."""
        i8, f8 = np.int64, np.float64
        return ColumnGroup(
            "tracker",
            (Column("ids", i8, doc="track id"),
             Column("exist", f8, (2,), doc="existence-chain state (5.3, 6.15-6.17)"),
             Column("t_last", i8, doc="time of the state, ns"),
             Column("confirmed", bool, fill=False, doc="confirmed (never revoked)"),
             Column("updates", i8, fill=0, doc="scans with a plot of weight > 0.5"),
             Column("radar_mask", i8, fill=0, doc="bit i: radar_names[i] updated it"),
             Column("last_update", i8, doc="time of the last plot, ns"),
             Column("height", f8, fill=np.nan, doc="height of the last plot, m"),
             Column("coast_from", i8, doc="max_coast counts from here, ns"),
             Column("born", i8, doc="initiation time, ns")),
            init=self._new_rows,
        )  # fmt: skip

    def _new_rows(self, new: NewTracks) -> dict:
        """A new track's existence is ψ_init, its clocks its initiation time."""
        t, k = new.t, len(new)
        exist = np.column_stack([np.full(k, self.cfg.psi_init), np.zeros(k)])
        return {"exist": exist, "t_last": t, "last_update": t, "coast_from": t, "born": t}

    @staticmethod
    def _make_chain(cfg: TrackerConfig) -> ExistenceChain:
        if cfg.existence_chain == "mc1":
            return markov_chain_one(cfg.delta11, cfg.delta21, cfg.existence_period)
        return markov_chain_two(
            cfg.delta11,
            cfg.delta21,
            cfg.mc2_obs_to_unobs,
            cfg.mc2_unobs_to_obs,
            cfg.existence_period,
        )

    # ------------------------------------------------------------------ helpers
    @property
    def n(self) -> int:
        return len(self.tracks)

    @property
    def ids(self) -> np.ndarray:
        """The ids of the live tracks, in row order (a view of the store's column)."""
        return self.tracks.ids

    def existence(self) -> np.ndarray:
        return self.chain.existence(self.tracks.exist)

    def estimates(self) -> tuple[np.ndarray, np.ndarray]:
        """MMSE estimates x (n, d), P (n, d, d) of all tracks at their t_last."""
        return self.density.estimate(np.arange(self.n))

    def _count(self, key: str, value: int) -> None:
        self.totals[key] = self.totals.get(key, 0) + int(value)

    def _radar_bit(self, radar_id: str) -> int:
        if radar_id not in self.radar_names:
            if len(self.radar_names) >= 63:
                raise ValueError(f"radar {radar_id!r}: at most 63 radars per tracker")
            self.radar_names.append(radar_id)
        return 1 << self.radar_names.index(radar_id)

    def _add_tracks(self, x: np.ndarray, P: np.ndarray, t: np.ndarray) -> None:
        nn = len(x)
        if nn == 0:
            return
        ids = self._next_id + np.arange(nn)
        self._next_id += nn
        self.tracks.append(NewTracks(x, P, t.astype(np.int64)), ids=ids)

    def add_track(
        self,
        x: np.ndarray,
        P: np.ndarray,
        time_ns: int,
        existence: float | None = None,
        confirmed: bool = False,
    ) -> int:
        """Start a track from a known state ``x`` (d,) and covariance ``P`` (d, d) at
        ``time_ns`` with existence ``existence`` (default ψ_init); returns its id."""
        x = np.asarray(x, dtype=np.float64).reshape(1, self.d)
        P = np.asarray(P, dtype=np.float64).reshape(1, self.d, self.d)
        if not (np.isfinite(x).all() and np.isfinite(P).all()):
            raise ValueError("add_track: x and P must be finite")
        psi = self.cfg.psi_init if existence is None else float(existence)
        if not 0.0 < psi <= 1.0:
            raise ValueError(f"add_track: existence = {psi}: must be in (0, 1]")
        self._add_tracks(x, P, np.array([time_ns], dtype=np.int64))
        self.tracks.exist[-1] = (psi, 0.0)
        self.tracks.confirmed[-1] = confirmed
        return int(self.ids[-1])

    def delete_tracks(self, track_ids: np.ndarray) -> int:
        """Remove the tracks with these ids at once, without events (evaluation: the true
        tracks at the end of a Monte Carlo run). Unknown ids are ignored; returns the
        number of tracks removed."""
        drop = np.isin(self.ids, np.asarray(track_ids, dtype=np.int64).reshape(-1))
        if drop.any():
            self.tracks.keep(~drop)
        return int(drop.sum())

    def component_counts(self) -> dict[int, int]:
        """Number of mixture components of every track, by id (1 when the density has
        no components)."""
        counts = self.density.component_counts()
        return {int(i): int(c) for i, c in zip(self.ids, counts)}

    # ------------------------------------------------------------------ the step
    def step(self, batch: MeasurementBatch) -> TrackerOutput:
        """Apply one batch of plots; return all live tracks at the batch time."""
        b = batch.validated(self.k)
        m = len(b)
        stats = {"plots": m, "rejected": sum(b.rejected.values())}
        bit = self._radar_bit(b.radar_id)
        tr = self.tracks
        x, P = self.density.estimates_view()
        view = select_tracks(b, x, P, tr.t_last, self.pos, self.vel, self.cfg.coverage_sigma)
        t_pred = view.t_pred
        # the detection share of the tracks in coverage only (the others are not used)
        cand = np.flatnonzero(view.inside)
        seen, cone = detection_share(b, view, cand, tr.height[cand])
        is_blind = cone < self.cfg.blind_share
        blind = np.zeros(self.n, bool)
        blind[cand[is_blind]] = True
        sel = cand[~is_blind]
        share = np.zeros(self.n)  # by track row; only the rows in coverage are used
        share[cand] = seen * cone
        reporting = b.coverage is not None and b.coverage.detection == "reports"
        if reporting:  # silence about a track it has not reported lately is no miss
            timeout = b.coverage.report_timeout
            share[cand] *= self.reports.recent(cand, b.radar_id, b.time_ns, timeout)
        stats["tracks_in_coverage"] = len(sel)
        sel, late, t_tau = self.oosm.split(sel, view.t_sweep, stats)  # older: oosm_pass
        stats["tracks_blind"] = int(blind.sum())
        assigned, used = self._update(b, sel, t_pred, share, bit, stats)
        if len(late):
            assigned, used = self.oosm.apply(
                self.phases, b, late, t_tau, share, bit, assigned, used, stats
            )
            sel = np.union1d(sel, late)
        tr.height[:] = track_heights(tr.height, assigned, b.heights)
        tr.coast_from[:] = np.where(blind, np.maximum(tr.coast_from, t_pred), tr.coast_from)
        if reporting:
            self._record_reports(b, assigned)
        events: list[TrackEventRecord] = []
        if self.identity is not None:
            self.identity.flush(events, stats)
        assigned = self._manage(sel, assigned, int(b.time_ns), events, stats)
        new = self._initiate(b, used)
        if reporting and new:
            rows = np.arange(self.n - new, self.n)
            self.reports.record(rows, b.radar_id, self.tracks.born[rows])
        assigned = np.concatenate([assigned, np.full(new, -1, dtype=np.int64)])
        stats["initiated"] = new
        for k_, v in stats.items():
            self._count(k_, v)
        return self._output(b, assigned, events, stats)

    def _record_reports(self, b: MeasurementBatch, assigned: np.ndarray) -> None:
        """The tracks whose most likely plot is in this report-based batch were reported
        at that plot's time (:mod:`.report_clock`)."""
        rows = np.flatnonzero(assigned >= 0)
        times = np.full(len(b), int(b.time_ns), np.int64) if b.plot_times is None else b.plot_times
        self.reports.record(rows, b.radar_id, np.asarray(times)[assigned[rows]])

    def _update(self, b, sel, t_pred, share, bit, stats) -> tuple[np.ndarray, np.ndarray]:
        """The ordinary prediction and update of the tracks ``sel`` (steps 2-6 of the
        module docstring); returns each track's most likely plot and the plots used."""
        tr = self.tracks
        dt = (t_pred[sel] - tr.t_last[sel]) * NS
        pred = self.density.predict(sel, dt)
        t_e = existence_clock(tr.t_last[sel], tr.coast_from[sel])
        exist_pred = self.chain.predict(tr.exist[sel], np.maximum(t_pred[sel] - t_e, 0) * NS)
        table = self.density.likelihoods(pred, b.z, b.R, self.g)
        stats["gated_pairs"] = len(table.tp_track)
        res = self.phases.associate(b, pred, table, exist_pred[:, 0], share[sel])
        self.density.update(pred, table, res.beta0, res.beta)
        self.oosm.record(sel, t_pred, pred)
        stats.update(res.stats)
        stats.update(self.density.stats)
        tr.exist[sel] = self.chain.update(exist_pred, res.psi_post)
        tr.t_last[sel] = t_pred[sel]
        assigned = self.phases.record_hits(sel, t_pred, res, table, bit)
        self.phases.attribute(b, sel, res, table)
        return assigned, self.phases.used_plots(len(b), table, res)

    # ------------------------------------------------------------------ management
    def _manage(
        self,
        sel: np.ndarray,
        assigned: np.ndarray,
        t_batch: int,
        events: list[TrackEventRecord],
        stats: dict[str, int],
    ) -> np.ndarray:
        """Duplicates first (so that an established track keeps its id), confirmation of
        the survivors, termination; removes the dropped tracks and returns ``assigned``
        for the remaining ones ([thesis] §7.1-7.2)."""
        keep = self._remove_duplicates(sel, assigned, t_batch, events, stats)
        self._confirm(sel, keep, t_batch, events)
        keep &= ~self._terminate(keep, t_batch, events, stats)
        if not keep.all():
            assigned = assigned[keep]
            self.tracks.keep(keep)
        return assigned

    def _remove_duplicates(
        self,
        sel: np.ndarray,
        assigned: np.ndarray,
        t_batch: int,
        events: list[TrackEventRecord],
        stats: dict[str, int],
    ) -> np.ndarray:
        """Tracks whose most likely plot of this batch is the same one and whose estimates
        coincide: the weaker is dropped (returned mask False)."""
        has_plot = np.flatnonzero(assigned[sel] >= 0)
        a, c = shared_plot_pairs(has_plot, assigned[sel][has_plot])
        keep = np.ones(self.n, bool)
        if len(a) == 0:
            return keep
        tr = self.tracks
        psi_all = self.existence()
        x, P = self.density.estimates_view()
        scans = tr.updates if self.cfg.duplicate_survivor == "established" else None
        loser, winner = duplicates(sel[a], sel[c], x, P, psi_all, tr.confirmed, scans, self.g_dup)
        keep[loser] = False
        for lo, wi in zip(loser, winner):
            if tr.confirmed[lo]:
                events.append(
                    TrackEventRecord(
                        t_batch,
                        "merged",
                        int(tr.ids[lo]),
                        float(psi_all[lo]),
                        int(tr.ids[wi]),
                        "duplicate of a track on the same target",
                    )
                )
        stats["duplicates_removed"] = len(loser)
        return keep

    def _confirm(
        self, sel: np.ndarray, keep: np.ndarray, t_batch: int, events: list[TrackEventRecord]
    ) -> None:
        """Confirmation of the updated tracks (hysteresis: never revoked), then their
        re-identification (:mod:`.reidentification`)."""
        cfg, tr = self.cfg, self.tracks
        psi_sel = self.chain.existence(tr.exist[sel]) if len(sel) else np.zeros(0)
        if cfg.life_cycle == "m_of_n":
            conf = to_confirm_m_of_n(tr.confirmed[sel], tr.updates[sel], cfg.confirm_m_of_n[0])
        else:
            conf = to_confirm(
                psi_sel, tr.confirmed[sel], tr.updates[sel], cfg.tau_confirm,
                cfg.confirm_min_updates,
            )  # fmt: skip
        rows = sel[conf & keep[sel]]
        tr.confirmed[rows] = True
        psi_rows = self.chain.existence(tr.exist[rows]) if len(rows) else np.zeros(0)
        found = None if self.reid is None else self.reid.reidentify(rows, t_batch)
        previous = np.full(len(rows), -1, np.int64) if found is None else found.previous
        if found is not None:
            self._count("reidentified", int((previous >= 0).sum()))
            self._take_over(rows, found.ended, previous, keep, t_batch, events)
        for r, old, psi_r in zip(rows, previous, psi_rows):
            why = "" if old < 0 else f"re-identified (tentative id {old})"
            events.append(
                TrackEventRecord(t_batch, "confirmed", int(tr.ids[r]), float(psi_r), reason=why)
            )
        if self.identity is not None and len(rows):
            self.identity.confirmed(rows, t_batch)
            self.identity.flush(events, {})

    def _take_over(self, rows, ended, previous, keep, t_batch, events) -> None:
        """The live tracks ``ended`` (rows, −1: none) that the newly confirmed ``rows``
        continue (:mod:`.reidentification`, L1-L3) end now: their ``terminated`` event
        comes before the ``confirmed`` event of the same id on the new row, which adds
        their scans with a plot and radars to its own; ``keep`` drops them."""
        tr = self.tracks
        hit = np.flatnonzero(ended >= 0)
        if not len(hit):
            return
        old, new = ended[hit], rows[hit]
        psi = self.chain.existence(tr.exist[old])
        for o, tentative, p in zip(old, previous[hit], psi):
            why = f"continued by tentative id {tentative}"
            events.append(TrackEventRecord(t_batch, "terminated", int(tr.ids[o]), float(p),
                                           reason=why))  # fmt: skip
        tr.updates[new] += tr.updates[old]
        tr.radar_mask[new] |= tr.radar_mask[old]
        keep[old] = False
        self._count("taken_over", len(hit))

    def _terminate(
        self,
        keep: np.ndarray,
        t_batch: int,
        events: list[TrackEventRecord],
        stats: dict[str, int],
    ) -> np.ndarray:
        """Tracks to end: existence predicted to the batch time below τ_t, or no plot for
        ``max_coast`` seconds (counted from the later of the last plot and the last batch
        that found the track in a cone of silence, :mod:`.coverage`)."""
        cfg, tr = self.cfg, self.tracks
        coasting = np.zeros(self.n, bool)
        if cfg.max_coast is not None:
            coasting = (t_batch - np.maximum(tr.last_update, tr.coast_from)) > round(
                cfg.max_coast / NS
            )
        # the existence clock stands still in a cone of silence (:mod:`.coverage`)
        dt = np.maximum(t_batch - existence_clock(tr.t_last, tr.coast_from), 0) * NS
        # exact existence prediction only where the closed form says ψ can be near τ_t
        # (usually no track) and for the coasting ones
        level = cfg.tau_terminate + TERMINATION_MARGIN
        psi_now = self.chain.existence_below(tr.exist, dt, level, coasting)
        ended, why = to_terminate(psi_now, cfg.tau_terminate), "existence below tau_t"
        if cfg.life_cycle == "m_of_n":  # the counts decide, not ψ (reported as it is)
            psi_now = self.existence()
            ended = to_terminate_by_count(
                tr.confirmed, tr.updates, tr.scans, tr.misses, cfg.confirm_m_of_n,
                cfg.max_misses,
            )  # fmt: skip
            why = "max_misses scans without a plot"
        term = (ended | coasting) & keep
        for r in np.flatnonzero(term & tr.confirmed):
            events.append(
                TrackEventRecord(
                    t_batch,
                    "terminated",
                    int(tr.ids[r]),
                    float(psi_now[r]),
                    reason="no plot for max_coast" if coasting[r] else why,
                )
            )
        stats["terminated"] = int(term.sum())
        if self.reid is not None:
            self.reid.ended(np.flatnonzero(term & tr.confirmed))
        return term

    def _initiate(self, b: MeasurementBatch, used: np.ndarray) -> int:
        """New tracks from the plots not ``used`` by tracks (two-point or one-point,
        [thesis] §3.5)."""
        cfg = self.cfg
        m = len(b)
        uid0 = self._next_uid
        self._next_uid += m
        free = np.flatnonzero(~used)
        if cfg.initiation == "none" or len(free) == 0:
            return 0
        if b.plot_times is None:
            t = np.full(len(free), int(b.time_ns), dtype=np.int64)
        else:
            t = np.asarray(b.plot_times, dtype=np.int64)[free]
        z, R = b.z[free], b.R[free]
        before = self.n
        if cfg.initiation == "one_point":
            self._add_tracks(*one_point(z, R, cfg.v_max), t)
            self._first_sightings(b, before, free, t)
            return self.n - before
        # pair with the buffered plots not expired; keep those neither expired nor paired
        old, new, dt, stay = pair_plots(
            self.buffer, z, t, cfg.v_max, cfg.init_min_dt, cfg.init_max_dt, int(b.time_ns)
        )
        if len(old):
            x, P = two_point(self.buffer.z[old], self.buffer.R[old], z[new], R[new], dt)
            self._add_tracks(x, P, t[new])
            self._first_sightings(b, before, free[new], t[new])
        if not stay.all():
            self.buffer.keep(stay)
        self.buffer.add(z, R, t, uid0 + free)
        return self.n - before

    def _first_sightings(self, b: MeasurementBatch, first_row: int, plots, t) -> None:
        """The identity of the plots ``plots`` that started the tracks from row
        ``first_row`` on, at times ``t`` (:mod:`.identity`)."""
        if self.identity is not None and b.identity is not None:
            self.identity.observe(b.identity, np.arange(first_row, self.n), plots, t)

    def _output(
        self,
        b: MeasurementBatch,
        assigned: np.ndarray,
        events: list[TrackEventRecord],
        stats: dict[str, int],
    ) -> TrackerOutput:
        # a late batch (older than the newest one) does not move the output back in time:
        # the tracks are predicted to the newest time (never backwards)
        self.newest_ns = max(int(b.time_ns), self.newest_ns)
        return self.output(b.radar_id, assigned, events, stats, b)

    def output(
        self,
        radar_id: str = "",
        assigned: np.ndarray | None = None,
        events: list[TrackEventRecord] | None = None,
        stats: dict[str, int] | None = None,
        batch: MeasurementBatch | None = None,
    ) -> TrackerOutput:
        """All live tracks at the newest batch time (``newest_ns``): the output of the
        last step, or of the state restored from a snapshot (no plot assigned)."""
        tr = self.tracks
        x, P = (a.copy() for a in self.density.estimates_view())
        snapshot = OutputPrediction(
            self.newest_ns,
            x,
            P,
            tr.t_last.copy(),
            tr.exist.copy(),
            self.model,
            self.chain,
            existence_clock(tr.t_last, tr.coast_from),
        )
        return TrackerOutput(
            time_ns=self.newest_ns,
            radar_id=radar_id,
            ids=tr.ids.copy(),
            prediction=snapshot,
            confirmed=tr.confirmed.copy(),
            updates=tr.updates.copy(),
            radar_mask=tr.radar_mask.copy(),
            radar_names=list(self.radar_names),
            last_update_ns=tr.last_update.copy(),
            assigned_plot=np.full(self.n, -1, np.int64) if assigned is None else assigned,
            events=[] if events is None else events,
            stats={} if stats is None else stats,
            batch=batch,
            identity=None if self.identity is None else self.identity.output(self.newest_ns),
        )

    # ------------------------------------------------------------------ snapshots
    def to_snapshot(self) -> dict:
        """The whole state, by declared names (:mod:`schemas.snapshot`): the version, the
        configuration that produced it, the track store's columns, the parts' own state
        (density components or random generator, terminated tracks, buffered plots) and
        the counters. Arrays are views: serialise before the next step."""
        return {
            "version": self.SNAPSHOT_VERSION,
            "config": self.cfg.model_dump(mode="json"),
            "tracks": self.tracks.to_snapshot(),
            "density": self.density.to_snapshot(),
            "reidentification": None if self.reid is None else self.reid.to_snapshot(),
            "plot_buffer": self.buffer.to_snapshot(),
            "report_clock": self.reports.to_snapshot(),
            "next_id": self._next_id,
            "next_uid": self._next_uid,
            "newest_ns": self.newest_ns,
            "radar_names": list(self.radar_names),
            "totals": dict(self.totals),
        }

    def from_snapshot(self, snap) -> None:
        """Hold the state of :meth:`to_snapshot`, on a tracker just made with the same
        configuration. A snapshot of another version or configuration, or whose parts do
        not fit their declarations or each other, is a :class:`SnapshotError`; the tracker
        is then to be discarded (see :func:`tracker_from_snapshot`)."""
        snap = check_version(snap, "tracker", self.SNAPSHOT_VERSION)
        if snap.get("config") != self.cfg.model_dump(mode="json"):
            raise SnapshotError("the tracker configuration differs from the snapshot's")
        if self.n:
            raise SnapshotError("a snapshot is restored into a tracker without tracks")
        self.tracks.from_snapshot(snap.get("tracks"))
        self.density.from_snapshot(snap.get("density"))
        if self.reid is not None:
            self.reid.from_snapshot(snap.get("reidentification"))
        self.buffer.from_snapshot(snap.get("plot_buffer"))
        self.reports.from_snapshot(snap.get("report_clock"))
        next_id, names = entry(snap, "next_id", int), strings(snap, "radar_names")
        ids = self.tracks.ids
        if len(ids) and (ids.min() < 1 or ids.max() >= next_id or len(np.unique(ids)) < len(ids)):
            raise SnapshotError(f"track ids not unique and within 1 … {next_id - 1}")
        if len(names) > 63 or (self.tracks.radar_mask >> len(names)).any():
            raise SnapshotError(f"radar masks beyond the {len(names)} radar names")
        self._next_id, self._next_uid = next_id, entry(snap, "next_uid", int)
        self.newest_ns, self.radar_names = entry(snap, "newest_ns", int), list(names)
        self.totals = dict(counts(snap, "totals"))


def tracker_from_snapshot(snap) -> Tracker:
    """A tracker holding a snapshot (:meth:`Tracker.to_snapshot`), built with the
    configuration the snapshot records; :class:`SnapshotError` if it does not fit."""
    snap = check_version(snap, "tracker", Tracker.SNAPSHOT_VERSION)
    try:
        cfg = TrackerConfig.model_validate(snap.get("config"))
    except ValueError as e:  # pydantic's ValidationError
        raise SnapshotError(f"tracker configuration: {str(e)[:200]}") from None
    tracker = Tracker(cfg)
    tracker.from_snapshot(snap)
    return tracker
