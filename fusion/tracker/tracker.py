"""The existence-based multi-target tracker: a short sequence of swappable parts.

``Tracker(config).step(batch) -> TrackerOutput`` applies one :class:`MeasurementBatch`
(one radar sector or scan, system frame) to all tracks. Per batch:

1. **Coverage** (:mod:`.coverage`, multi-radar): only tracks the batch could have seen
   are predicted to their illumination time and updated; the others keep their state
   and existence (a radar that does not see a region does not erode its tracks).
2. **Prediction** of the track density (:mod:`.density`: Gaussian mixture with Singer
   memory, or an IMM per component, 5.4-5.5, spec 01 §5; particle clouds for ipf/lmipf,
   :mod:`fusion.particles`, spec 04 A4) and of existence (Markov chain,
   :mod:`.existence`, 5.3) over per-track dt arrays.
3. **Likelihoods**: the density gates the plots and returns the track × plot table
   p^τ_i = likelihood / P_G (5.7-5.10, 4.17).
4. **Clutter** density per table row (:mod:`.clutter`): known or estimated (2.35).
5. **Association** part from the registry (:mod:`.registry`, :mod:`.associators`):
   single (IPDA/ITS, 5.16-5.18), lm (6.12-6.22), joint (6.1-6.8), gnn (MAP event).
6. **Update** of the density with β₀, β (ITS children 5.12-5.15, merge, pruning).
7. **Management** (:mod:`.management`): duplicate removal, confirmation, termination;
   **initiation** (:mod:`.initiation`) from the plots no track gated.

All arrays run over tracks, components and plots; the only Python loops are over JIPDA
clusters with more than one track and GNN clusters.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from skyfuse.fusion.association.gating import gate_probability, gate_threshold
from skyfuse.fusion.models.cv import ConstantVelocity

from .associators import AssociationProblem
from .clutter import clutter_density
from .config import TrackerConfig
from .coverage import detection_share, existence_clock, select_tracks, track_heights
from .density.base import GatedTable, Prediction, TrackDensity
from .existence import ExistenceChain, markov_chain_one, markov_chain_two
from .initiation import PlotBuffer, one_point, pair_plots, two_point
from .ipda import AssociationResult
from .management import (
    duplicates,
    shared_plot_pairs,
    to_confirm,
    to_confirm_m_of_n,
    to_terminate,
    to_terminate_by_count,
)
from .measurements import MeasurementBatch
from .oosm_pass import OutOfSequence
from .registry import ASSOCIATIONS, make_density
from .reidentification import TerminatedTracks, keeps_fix

NS = 1e-9
#: Tracks whose closed-form predicted existence is at least τ_t + this are not terminated
#: without the exact chain prediction (the two differ by rounding, ~1e-15).
TERMINATION_MARGIN = 1e-6


@dataclass
class TrackEventRecord:
    """A life-cycle event: kind is ``confirmed``, ``terminated`` or ``merged`` (``track_id``
    removed as a duplicate of ``other_track_id``)."""

    time_ns: int
    kind: str
    track_id: int
    existence: float
    other_track_id: int | None = None
    reason: str = ""


@dataclass
class OutputPrediction:
    """The track estimates x (n, d), P (n, d, d) and existence-chain states (n, 2) at
    their times ``t_last`` (n,) ns after one step (copies), predicted on demand to
    ``time_ns`` with the output model (CV, spec 02 5.4) and the existence chain (5.3):
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
    batch for the track (−1: none or not in coverage), events, stats, and the validated
    batch (its ``target_ids`` serve evaluation).

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

    Track arrays (rows aligned with ``self.density``): ids, exist (n, 2) Markov-chain
    state, t_last (ns), confirmed, updates, radar_mask, last_update (ns), height (m, of
    the last plot, NaN unknown), coast_from (ns: the last plot or the last batch that
    found the track in a cone of silence; ``max_coast`` counts from it), scans (batches
    that saw the track, the one that started it included) and misses (consecutive of them
    without a plot; both for ``life_cycle = "m_of_n"``)."""

    def __init__(self, config: TrackerConfig | None = None) -> None:
        self.cfg = cfg = config or TrackerConfig()
        # output model: predicts the CV-layout estimates between batches (spec 02 5.4)
        self.model = ConstantVelocity(q=cfg.q, ndim=cfg.ndim, q_vertical=cfg.q_vertical)
        self.d = self.model.dim
        self.k = cfg.ndim
        self.pos = np.array(self.model.position_index)
        self.vel = self.pos + 1
        self.g = gate_threshold(cfg.p_gate, self.k)
        self.P_G = gate_probability(self.g, self.k)
        self.g_dup = gate_threshold(cfg.duplicate_p, self.d)
        self.chain = self._make_chain(cfg)
        self.density: TrackDensity = make_density(cfg)
        self.associate = ASSOCIATIONS[cfg.association]
        self.oosm = OutOfSequence(self.density, cfg.oosm)
        self.newest_ns = 0
        """The newest batch time applied, ns: outputs never go back in time."""
        self.ids = np.zeros(0, np.int64)
        self.exist = np.zeros((0, 2))
        self.t_last = np.zeros(0, np.int64)
        self.confirmed = np.zeros(0, bool)
        self.updates = np.zeros(0, np.int64)
        self.radar_mask = np.zeros(0, np.int64)
        self.last_update = np.zeros(0, np.int64)
        self.height = np.zeros(0)
        self.coast_from = np.zeros(0, np.int64)
        self.born = np.zeros(0, np.int64)
        self.fix_x = np.zeros((0, self.d))
        self.fix_P = np.zeros((0, self.d, self.d))
        self.fix_t = np.zeros(0, np.int64)
        self.scans = np.zeros(0, np.int64)
        self.misses = np.zeros(0, np.int64)
        self.terminated = TerminatedTracks(
            self.model,
            cfg.reid_max_gap or 0.0,
            cfg.reid_q,
            cfg.reid_p,
            cfg.reid_max_sigma,
            cfg.reid_min_speed,
        )
        self.buffer = PlotBuffer.empty(self.k)
        self.radar_names: list[str] = []
        self._next_id = 1
        self._next_uid = 1
        self.totals: dict[str, int] = {}

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
        return len(self.ids)

    def existence(self) -> np.ndarray:
        return self.chain.existence(self.exist)

    def estimates(self) -> tuple[np.ndarray, np.ndarray]:
        """MMSE estimates x (n, d), P (n, d, d) of all tracks at their t_last."""
        return self.density.estimate(np.arange(self.n))

    def _estimates_view(self) -> tuple[np.ndarray, np.ndarray]:
        """The estimates of all tracks for reading only: the density's own arrays when it
        offers them (``estimates_view``, no copy of every track per batch), else a copy."""
        view = getattr(self.density, "estimates_view", None)
        return view() if view is not None else self.estimates()

    def _count(self, key: str, value: int) -> None:
        self.totals[key] = self.totals.get(key, 0) + int(value)

    def _radar_bit(self, radar_id: str) -> int:
        if radar_id not in self.radar_names:
            if len(self.radar_names) >= 63:
                raise ValueError(f"radar {radar_id!r}: at most 63 radars per tracker")
            self.radar_names.append(radar_id)
        return 1 << self.radar_names.index(radar_id)

    _ARRAYS = (
        "ids", "exist", "t_last", "confirmed", "updates", "radar_mask", "last_update",
        "height", "coast_from", "born", "fix_x", "fix_P", "fix_t", "scans", "misses",
    )  # fmt: skip

    def _remove(self, keep: np.ndarray) -> None:
        for name in self._ARRAYS:
            setattr(self, name, getattr(self, name)[keep])
        self.density.keep(keep)

    def _add_tracks(self, x: np.ndarray, P: np.ndarray, t: np.ndarray) -> None:
        nn = len(x)
        if nn == 0:
            return
        t = t.astype(np.int64)
        zeros = np.zeros(nn, np.int64)
        new = {
            "ids": self._next_id + np.arange(nn),
            "exist": np.column_stack([np.full(nn, self.cfg.psi_init), np.zeros(nn)]),
            "t_last": t,
            "confirmed": np.zeros(nn, bool),
            "updates": zeros,
            "radar_mask": zeros,
            "last_update": t,
            "height": np.full(nn, np.nan),
            "coast_from": t,
            "born": t,
            "fix_x": x,
            "fix_P": P,
            "fix_t": t,
            "scans": np.ones(nn, np.int64),
            "misses": zeros,
        }
        self._next_id += nn
        for name in self._ARRAYS:
            setattr(self, name, np.concatenate([getattr(self, name), new[name]]))
        self.density.add(x, P)

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
        self.exist[-1] = (psi, 0.0)
        self.confirmed[-1] = confirmed
        return int(self.ids[-1])

    def delete_tracks(self, track_ids: np.ndarray) -> int:
        """Remove the tracks with these ids at once, without events (evaluation: the true
        tracks at the end of a Monte Carlo run, spec 03 §2 "Across runs"). Unknown ids are
        ignored; returns the number of tracks removed."""
        drop = np.isin(self.ids, np.asarray(track_ids, dtype=np.int64).reshape(-1))
        if drop.any():
            self._remove(~drop)
        return int(drop.sum())

    def component_counts(self) -> dict[int, int]:
        """Number of mixture components of every track, by id (1 when the density has
        no components)."""
        counter = getattr(self.density, "component_counts", None)
        counts = counter() if counter is not None else np.ones(self.n, np.int64)
        return {int(i): int(c) for i, c in zip(self.ids, counts)}

    # ------------------------------------------------------------------ the step
    def step(self, batch: MeasurementBatch) -> TrackerOutput:
        """Apply one batch of plots; return all live tracks at the batch time."""
        b = batch.validated(self.k)
        m = len(b)
        stats = {"plots": m, "rejected": sum(b.rejected.values())}
        bit = self._radar_bit(b.radar_id)
        x, P = self._estimates_view()
        view = select_tracks(b, x, P, self.t_last, self.pos, self.vel, self.cfg.coverage_sigma)
        t_pred = view.t_pred
        # the detection share of the tracks in coverage only (the others are not used)
        cand = np.flatnonzero(view.inside)
        seen, cone = detection_share(b, view, cand, self.height[cand])
        is_blind = cone < self.cfg.blind_share
        blind = np.zeros(self.n, bool)
        blind[cand[is_blind]] = True
        sel = cand[~is_blind]
        share = np.zeros(self.n)  # by track row; only the rows in coverage are used
        share[cand] = seen * cone
        stats["tracks_in_coverage"] = len(sel)
        sel, late, t_tau = self.oosm.split(self, sel, view.t_sweep, stats)  # older: oosm_pass
        stats["tracks_blind"] = int(blind.sum())
        dt = (t_pred[sel] - self.t_last[sel]) * NS
        pred = self.density.predict(sel, dt)
        t_e = existence_clock(self.t_last[sel], self.coast_from[sel])
        exist_pred = self.chain.predict(self.exist[sel], np.maximum(t_pred[sel] - t_e, 0) * NS)
        table = self.density.likelihoods(pred, b.z, b.R, self.g)
        stats["gated_pairs"] = len(table.tp_track)
        res = self._associate(b, pred, table, exist_pred[:, 0], share[sel])
        self.density.update(pred, table, res.beta0, res.beta)
        self.oosm.record(self, sel, t_pred, pred)
        stats.update(res.stats)
        stats.update(getattr(self.density, "stats", {}))
        self.exist[sel] = self.chain.update(exist_pred, res.psi_post)
        self.t_last[sel] = t_pred[sel]
        assigned = self._record_hits(sel, t_pred, res, table, bit)
        used = self._used_plots(m, table, res)
        if len(late):
            assigned, used = self.oosm.apply(
                self, b, late, t_tau, share, bit, assigned, used, stats
            )
            sel = np.union1d(sel, late)
        self.height = track_heights(self.height, assigned, b.heights)
        self.coast_from = np.where(blind, np.maximum(self.coast_from, t_pred), self.coast_from)
        events: list[TrackEventRecord] = []
        assigned = self._manage(sel, assigned, int(b.time_ns), events, stats)
        new = self._initiate(b, used)
        assigned = np.concatenate([assigned, np.full(new, -1, dtype=np.int64)])
        stats["initiated"] = new
        for k_, v in stats.items():
            self._count(k_, v)
        return self._output(b, assigned, events, stats)

    def _associate(
        self,
        b: MeasurementBatch,
        pred: Prediction,
        table: GatedTable,
        psi_det: np.ndarray,
        share: np.ndarray,
    ) -> AssociationResult:
        """Clutter density per row, then the configured association part; P_D of each
        row without a gated plot scaled by its detection ``share`` (:mod:`.coverage`; a
        plot in the gate shows the radar saw where the track is)."""
        cfg = self.cfg
        share = share.copy()
        share[table.tp_track] = 1.0
        pdpg = float(b.p_detection) * self.P_G * share
        # the track-level moments only for the estimated clutter (known: not used)
        estimated = cfg.clutter == "estimated"
        rho = clutter_density(
            cfg.clutter,
            b.clutter_density,
            cfg.clutter_density_floor,
            table.tp_track,
            table.tp_plot,
            pred.S0 if estimated else None,
            b.R,
            pdpg,
            psi_det,
            self.g,
            z=b.z,
            z_mean=pred.z_mean if estimated else None,
            volume_floor=cfg.clutter_volume,
        )
        problem = AssociationProblem(
            psi_det,
            pdpg,
            table.tp_track,
            table.tp_plot,
            len(b),
            table.p,
            rho,
            cfg.lm_prior_density,
            cfg.jipda_max_events,
        )
        return self.associate(problem)

    def _record_hits(
        self,
        sel: np.ndarray,
        t_pred: np.ndarray,
        res: AssociationResult,
        table: GatedTable,
        bit: int,
    ) -> np.ndarray:
        """Update counters of detected tracks (weight of a plot > 0.5) and return each
        track's most likely plot of the batch (−1: none, or β₀ larger)."""
        hit = sel[(1.0 - res.beta0) > 0.5]
        self.scans[sel] += 1
        self.misses[sel] += 1
        self.misses[hit] = 0
        self.updates[hit] += 1
        self.radar_mask[hit] |= bit
        self.last_update[hit] = t_pred[hit]
        if self.cfg.reid_max_gap is not None and len(hit):
            self._update_fixes(hit, t_pred[hit])
        assigned = np.full(self.n, -1, dtype=np.int64)
        if len(res.beta):
            tp_track, tp_plot = table.tp_track, table.tp_plot
            order = np.lexsort((-res.beta, tp_track))
            first = np.concatenate(([True], tp_track[order][1:] != tp_track[order][:-1]))
            best = order[first]
            good = res.beta[best] > res.beta0[tp_track[best]]
            assigned[sel[tp_track[best[good]]]] = tp_plot[best[good]]
        return assigned

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
        for the remaining ones (spec 02 §8, spec 03 §2)."""
        keep = self._remove_duplicates(sel, assigned, t_batch, events, stats)
        self._confirm(sel, keep, t_batch, events)
        keep &= ~self._terminate(keep, t_batch, events, stats)
        if not keep.all():
            assigned = assigned[keep]
            self._remove(keep)
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
        psi_all = self.existence()
        x, P = self._estimates_view()
        scans = self.updates if self.cfg.duplicate_survivor == "established" else None
        loser, winner = duplicates(sel[a], sel[c], x, P, psi_all, self.confirmed, scans, self.g_dup)
        keep[loser] = False
        for lo, wi in zip(loser, winner):
            if self.confirmed[lo]:
                events.append(
                    TrackEventRecord(
                        t_batch,
                        "merged",
                        int(self.ids[lo]),
                        float(psi_all[lo]),
                        int(self.ids[wi]),
                        "duplicate of a track on the same target",
                    )
                )
        stats["duplicates_removed"] = len(loser)
        return keep

    def _confirm(
        self, sel: np.ndarray, keep: np.ndarray, t_batch: int, events: list[TrackEventRecord]
    ) -> None:
        """Confirmation of the updated tracks (hysteresis: never revoked)."""
        cfg = self.cfg
        psi_sel = self.chain.existence(self.exist[sel]) if len(sel) else np.zeros(0)
        if cfg.life_cycle == "m_of_n":
            conf = to_confirm_m_of_n(self.confirmed[sel], self.updates[sel], cfg.confirm_m_of_n[0])
        else:
            conf = to_confirm(
                psi_sel, self.confirmed[sel], self.updates[sel], cfg.tau_confirm,
                cfg.confirm_min_updates,
            )  # fmt: skip
        rows = sel[conf & keep[sel]]
        self.confirmed[rows] = True
        psi_rows = self.chain.existence(self.exist[rows]) if len(rows) else np.zeros(0)
        previous = self._reidentify(rows, t_batch)
        for r, old, psi_r in zip(rows, previous, psi_rows):
            why = "" if old < 0 else f"re-identified (tentative id {old})"
            events.append(
                TrackEventRecord(t_batch, "confirmed", int(self.ids[r]), float(psi_r), reason=why)
            )

    def _update_fixes(self, hit: np.ndarray, t: np.ndarray) -> None:
        """The re-identification fixes of the tracks ``hit`` by a plot at times ``t`` ns:
        their new estimates, unless the old fix stays more informative (R1')."""
        x, P = self.density.estimate(hit)
        cfg = self.cfg
        old = keeps_fix(self.fix_P[hit], self.fix_t[hit], P, t, cfg.reid_q)
        new = hit[~old]
        self.fix_x[new], self.fix_P[new], self.fix_t[new] = x[~old], P[~old], t[~old]

    def _reidentify(self, rows: np.ndarray, t_batch: int) -> np.ndarray:
        """Newly confirmed ``rows`` that continue a recently terminated track take its id
        (:mod:`.reidentification`); returns their former ids (−1: not re-identified)."""
        previous = np.full(len(rows), -1, np.int64)
        if self.cfg.reid_max_gap is None or len(rows) == 0:
            return previous
        self.terminated.expire(t_batch)
        if len(self.terminated) == 0:
            return previous
        x, P = self.density.estimate(rows)
        j = self.terminated.match(x, P, self.t_last[rows], self.born[rows])
        hit = j >= 0
        previous[hit] = self.ids[rows[hit]]
        self.ids[rows[hit]] = self.terminated.take(j[hit])
        self._count("reidentified", int(hit.sum()))
        return previous

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
        cfg = self.cfg
        coasting = np.zeros(self.n, bool)
        if cfg.max_coast is not None:
            coasting = (t_batch - np.maximum(self.last_update, self.coast_from)) > round(
                cfg.max_coast / NS
            )
        # the existence clock stands still in a cone of silence (:mod:`.coverage`)
        dt = np.maximum(t_batch - existence_clock(self.t_last, self.coast_from), 0) * NS
        # exact existence prediction only where the closed form says ψ can be near τ_t
        rows = np.arange(self.n)
        bound = self.chain.existence_bound(self.exist, dt)
        if bound is not None:
            rows = np.flatnonzero((bound < cfg.tau_terminate + TERMINATION_MARGIN) | coasting)
        psi_now = np.ones(self.n)
        if len(rows):  # (usually none: every track's bound is above τ_t)
            psi_now[rows] = self.chain.existence(self.chain.predict(self.exist[rows], dt[rows]))
        ended, why = to_terminate(psi_now, cfg.tau_terminate), "existence below tau_t"
        if cfg.life_cycle == "m_of_n":  # the counts decide, not ψ (reported as it is)
            psi_now = self.existence()
            ended = to_terminate_by_count(
                self.confirmed, self.updates, self.scans, self.misses, cfg.confirm_m_of_n,
                cfg.max_misses,
            )  # fmt: skip
            why = "max_misses scans without a plot"
        term = (ended | coasting) & keep
        for r in np.flatnonzero(term & self.confirmed):
            events.append(
                TrackEventRecord(
                    t_batch,
                    "terminated",
                    int(self.ids[r]),
                    float(psi_now[r]),
                    reason="no plot for max_coast" if coasting[r] else why,
                )
            )
        stats["terminated"] = int(term.sum())
        ended = np.flatnonzero(term & self.confirmed)
        if self.cfg.reid_max_gap is not None and len(ended):
            self.terminated.add(
                self.ids[ended], self.fix_x[ended], self.fix_P[ended], self.fix_t[ended]
            )
        return term

    def _used_plots(self, m: int, table: GatedTable, res: AssociationResult) -> np.ndarray:
        """Plots that may not start tracks: gated by any track (``init_free_weight`` None),
        or claimed by the tracks with a total association weight Σ_τ β^τ_i of at least
        ``init_free_weight`` (a plot of a second, closely spaced target that a track gates
        but does not take can then start its own track)."""
        used = np.zeros(m, bool)
        if self.cfg.init_free_weight is None:
            used[table.tp_plot] = True
            return used
        claimed = np.bincount(table.tp_plot, weights=res.beta, minlength=m)
        return claimed >= self.cfg.init_free_weight

    def _initiate(self, b: MeasurementBatch, used: np.ndarray) -> int:
        """New tracks from the plots not ``used`` by tracks (two-point or one-point,
        spec 02 §5)."""
        cfg = self.cfg
        m = len(b)
        uid = self._next_uid + np.arange(m, dtype=np.int64)
        self._next_uid += m
        free = np.flatnonzero(~used)
        if cfg.initiation == "none" or len(free) == 0:
            return 0
        plot_time = (
            np.asarray(b.plot_times, dtype=np.int64)
            if b.plot_times is not None
            else np.full(m, int(b.time_ns), dtype=np.int64)
        )
        z, R, t = b.z[free], b.R[free], plot_time[free]
        before = self.n
        if cfg.initiation == "one_point":
            self._add_tracks(*one_point(z, R, cfg.v_max), t)
            return self.n - before
        # drop expired buffered plots, pair, consume the paired ones, buffer the rest
        self.buffer.keep((int(b.time_ns) - self.buffer.time) * NS <= cfg.init_max_dt)
        old, new, dt = pair_plots(self.buffer, z, t, cfg.v_max, cfg.init_min_dt, cfg.init_max_dt)
        if len(old):
            x, P = two_point(self.buffer.z[old], self.buffer.R[old], z[new], R[new], dt)
            self._add_tracks(x, P, t[new])
            consumed = np.zeros(len(self.buffer), bool)
            consumed[old] = True
            self.buffer.keep(~consumed)
        self.buffer.add(z, R, t, uid[free])
        return self.n - before

    def _output(
        self,
        b: MeasurementBatch,
        assigned: np.ndarray,
        events: list[TrackEventRecord],
        stats: dict[str, int],
    ) -> TrackerOutput:
        # a late batch (older than the newest one) does not move the output back in time:
        # the tracks are predicted to the newest time (never backwards)
        t_out = max(int(b.time_ns), self.newest_ns)
        self.newest_ns = t_out
        x, P = self.estimates()
        snapshot = OutputPrediction(
            t_out,
            x,
            P,
            self.t_last.copy(),
            self.exist.copy(),
            self.model,
            self.chain,
            existence_clock(self.t_last, self.coast_from),
        )
        return TrackerOutput(
            time_ns=t_out,
            radar_id=b.radar_id,
            ids=self.ids.copy(),
            prediction=snapshot,
            confirmed=self.confirmed.copy(),
            updates=self.updates.copy(),
            radar_mask=self.radar_mask.copy(),
            radar_names=list(self.radar_names),
            last_update_ns=self.last_update.copy(),
            assigned_plot=assigned,
            events=events,
            stats=stats,
            batch=b,
        )
