"""The existence-based multi-target tracker: one framework, swappable association.

``Tracker(config).step(batch) -> TrackerOutput`` applies one :class:`MeasurementBatch`
(one radar sector or scan, system frame) to all tracks. Per batch:

1. **Coverage** (multi-radar): tracks whose lazily predicted position lies inside the
   batch's range/sector (within ``coverage_sigma`` σ) may have been detected; only they
   are predicted to their illumination time and updated. The others keep their state and
   existence (a radar that does not see a region does not erode its tracks).
2. **Prediction** of components (KF, 5.4-5.5) and existence (Markov chain, 5.3) over
   per-track dt arrays.
3. **Gating** of all components × plots with a spatial pre-gate (5.7), likelihoods
   p^c_i = N/P_G (4.17), track likelihoods p^τ_i = Σ ξ^c p^c_i (5.10).
4. **Clutter** density per track–plot row: known (sensor/map) or estimated (2.35).
5. **Association** by configuration: ``ipda``/``its`` (5.16-5.18), ``lmipda``/``lmits``
   (6.12-6.22), ``jipda``/``jits`` (6.1-6.8, LM fallback above the event cap), ``gnn``
   (MAP joint event).
6. **Components**: ITS children (5.12-5.15), Singer N-scan merge, pruning (§7.11).
7. **Management**: confirmation, duplicate removal, termination; **initiation** from the
   plots no track selected (two-point or one-point).

All arrays run over tracks, components and plots; the only Python loops are over JIPDA
clusters with more than one track and GNN clusters.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2
from skyfuse.fusion.filters.kalman import predict
from skyfuse.fusion.models.cv import ConstantVelocity

from . import components as comp
from .config import TrackerConfig
from .existence import ExistenceChain, markov_chain_one, markov_chain_two
from .gating import gate, gate_probability, gate_threshold, gate_volume
from .gnn import gnn_association
from .initiation import PlotBuffer, one_point, pair_plots, two_point
from .ipda import (
    AssociationResult,
    estimated_clutter_density,
    plots_in_track_gate,
    single_target,
)
from .its import component_update
from .jits import joint_association
from .lm_its import modified_clutter_density
from .management import duplicates, shared_plot_pairs, to_confirm, to_terminate
from .measurements import MeasurementBatch

NS = 1e-9


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
class TrackerOutput:
    """All live tracks after one batch, predicted to ``time_ns`` (arrays over tracks).

    ids (n,), states (n, d), covariances (n, d, d), existence (n,), confirmed (n,) bool,
    updates (n,) scans with a plot, radar_mask (n,) bit i = ``radar_names[i]`` updated the
    track, last_update_ns (n,), assigned_plot (n,) index of the most likely plot of this
    batch for the track (−1: none or not in coverage), events, stats, and the validated
    batch (its ``target_ids`` serve evaluation)."""

    time_ns: int
    radar_id: str
    ids: np.ndarray
    states: np.ndarray
    covariances: np.ndarray
    existence: np.ndarray
    confirmed: np.ndarray
    updates: np.ndarray
    radar_mask: np.ndarray
    radar_names: list[str]
    last_update_ns: np.ndarray
    assigned_plot: np.ndarray
    events: list[TrackEventRecord] = field(default_factory=list)
    stats: dict[str, int] = field(default_factory=dict)
    batch: MeasurementBatch | None = None

    def __len__(self) -> int:
        return len(self.ids)

    def radars_of(self, i: int) -> list[str]:
        m = int(self.radar_mask[i])
        return [name for b, name in enumerate(self.radar_names) if m >> b & 1]


class Tracker:
    """Multi-target tracker over arrays; see the module docstring for one step."""

    def __init__(self, config: TrackerConfig | None = None) -> None:
        self.cfg = cfg = config or TrackerConfig()
        self.model = ConstantVelocity(q=cfg.q, ndim=cfg.ndim, q_vertical=cfg.q_vertical)
        self.d = self.model.dim
        self.k = cfg.ndim
        self.H = self.model.H()
        self.pos = np.array(self.model.position_index)
        self.vel = self.pos + 1
        self.depth = cfg.memory_depth
        self.g = gate_threshold(cfg.p_gate, self.k)
        self.P_G = gate_probability(self.g, self.k)
        self.g_dup = float(chi2.ppf(cfg.duplicate_p, self.d))
        if cfg.existence_chain == "mc1":
            self.chain: ExistenceChain = markov_chain_one(
                cfg.delta11, cfg.delta21, cfg.existence_period
            )
        else:
            self.chain = markov_chain_two(
                cfg.delta11,
                cfg.delta21,
                cfg.mc2_obs_to_unobs,
                cfg.mc2_unobs_to_obs,
                cfg.existence_period,
            )
        # track arrays
        self.ids = np.zeros(0, np.int64)
        self.exist = np.zeros((0, 2))
        self.t_last = np.zeros(0, np.int64)
        self.confirmed = np.zeros(0, bool)
        self.updates = np.zeros(0, np.int64)
        self.radar_mask = np.zeros(0, np.int64)
        self.last_update = np.zeros(0, np.int64)
        self.x_out = np.zeros((0, self.d))
        self.P_out = np.zeros((0, self.d, self.d))
        self.mix = comp.Mixture.empty(self.d, self.depth)
        self.buffer = PlotBuffer.empty(self.k)
        self.radar_names: list[str] = []
        self._next_id = 1
        self._next_uid = 1
        self.totals: dict[str, int] = {}

    # ------------------------------------------------------------------ helpers
    @property
    def n(self) -> int:
        return len(self.ids)

    def existence(self) -> np.ndarray:
        return self.chain.existence(self.exist)

    def _count(self, key: str, value: int) -> None:
        self.totals[key] = self.totals.get(key, 0) + int(value)

    def _radar_bit(self, radar_id: str) -> int:
        if radar_id not in self.radar_names:
            if len(self.radar_names) >= 63:
                raise ValueError(f"radar {radar_id!r}: at most 63 radars per tracker")
            self.radar_names.append(radar_id)
        return 1 << self.radar_names.index(radar_id)

    def _predict_out(self, t_ns: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Track estimates and existence predicted (not stored) to ``t_ns``."""
        dt = np.maximum(t_ns - self.t_last, 0) * NS
        if self.n == 0:
            return self.x_out, self.P_out, np.zeros(0)
        x, P = predict(self.x_out, self.P_out, self.model.F(dt), self.model.Q(dt))
        psi = self.chain.existence(self.chain.predict(self.exist, dt))
        return x, P, psi

    def _remove(self, keep: np.ndarray) -> None:
        new_row = np.cumsum(keep) - 1
        for name in (
            "ids",
            "exist",
            "t_last",
            "confirmed",
            "updates",
            "radar_mask",
            "last_update",
            "x_out",
            "P_out",
        ):
            setattr(self, name, getattr(self, name)[keep])
        cm = keep[self.mix.track]
        self.mix = self.mix.take(np.flatnonzero(cm))
        self.mix.track = new_row[self.mix.track]

    def _add_tracks(self, x: np.ndarray, P: np.ndarray, t: np.ndarray, uid: np.ndarray) -> None:
        nn = len(x)
        if nn == 0:
            return
        rows = self.n + np.arange(nn)
        self.ids = np.concatenate([self.ids, self._next_id + np.arange(nn)])
        self._next_id += nn
        self.exist = np.concatenate(
            [self.exist, np.column_stack([np.full(nn, self.cfg.psi_init), np.zeros(nn)])]
        )
        self.t_last = np.concatenate([self.t_last, t.astype(np.int64)])
        self.confirmed = np.concatenate([self.confirmed, np.zeros(nn, bool)])
        self.updates = np.concatenate([self.updates, np.zeros(nn, np.int64)])
        self.radar_mask = np.concatenate([self.radar_mask, np.zeros(nn, np.int64)])
        self.last_update = np.concatenate([self.last_update, t.astype(np.int64)])
        self.x_out = np.concatenate([self.x_out, x])
        self.P_out = np.concatenate([self.P_out, P])
        hist = np.zeros((nn, self.depth), np.int64)
        if self.depth:
            hist[:, 0] = uid
        self.mix = comp.Mixture.concat(
            [self.mix, comp.Mixture(rows, np.ones(nn), x.copy(), P.copy(), hist)]
        )

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
        self._add_tracks(x, P, np.array([time_ns], dtype=np.int64), np.zeros(1, np.int64))
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
        """Number of mixture components of every track, by id."""
        counts = comp.components_per_track(self.mix, self.n)
        return {int(i): int(c) for i, c in zip(self.ids, counts)}

    def _select(self, batch: MeasurementBatch) -> tuple[np.ndarray, np.ndarray]:
        """Tracks the batch could have detected, and the time (ns) to predict each to."""
        t = np.full(self.n, batch.time_ns, dtype=np.int64)
        if batch.coverage is None or self.n == 0:
            return np.ones(self.n, bool), np.maximum(t, self.t_last)
        cov = batch.coverage
        dt = np.maximum(batch.time_ns - self.t_last, 0) * NS
        pos = self.x_out[:, self.pos] + self.x_out[:, self.vel] * dt[:, None]
        Ppos = self.P_out[:, self.pos, self.pos].sum(axis=1)
        Pvel = self.P_out[:, self.vel, self.vel].sum(axis=1)
        sigma = np.sqrt(Ppos + Pvel * dt**2)
        inside = cov.contains(pos, self.cfg.coverage_sigma * sigma)
        if cov.time_end > cov.time_start:
            t = cov.illumination_time(pos)
        return inside, np.maximum(t, self.t_last)

    # ------------------------------------------------------------------ the step
    def step(self, batch: MeasurementBatch) -> TrackerOutput:
        """Apply one batch of plots; return all live tracks at the batch time."""
        cfg = self.cfg
        b = batch.validated(self.k)
        m = len(b)
        t_batch = int(b.time_ns)
        events: list[TrackEventRecord] = []
        stats = {"plots": m, "rejected": sum(b.rejected.values())}
        bit = self._radar_bit(b.radar_id)
        uid = self._next_uid + np.arange(m, dtype=np.int64)
        self._next_uid += m
        plot_time = (
            np.asarray(b.plot_times, dtype=np.int64)
            if b.plot_times is not None
            else np.full(m, t_batch, dtype=np.int64)
        )

        # 1. coverage and per-track prediction times
        inside, t_pred = self._select(b)
        sel = np.flatnonzero(inside)
        ns = len(sel)
        stats["tracks_in_coverage"] = ns
        ci = np.flatnonzero(inside[self.mix.track])
        pred = self.mix.take(ci)
        dt_trk = (t_pred - self.t_last) * NS
        dtc = dt_trk[pred.track]
        pred.x, pred.P = predict(pred.x, pred.P, self.model.F(dtc), self.model.Q(dtc))
        loc = np.searchsorted(sel, pred.track)
        exist_pred = self.chain.predict(self.exist[sel], dt_trk[sel])
        psi_det = exist_pred[:, 0]

        # 2. gating and likelihoods (5.7-5.10, 4.17)
        y = pred.x[:, self.pos]
        HPH = pred.P[:, self.pos][:, :, self.pos]
        pairs = gate(y, HPH, b.z, b.R, self.g)
        p_pair = np.exp(pairs.log_pdf) / self.P_G
        key = loc[pairs.comp] * max(m, 1) + pairs.plot
        uniq, row = np.unique(key, return_inverse=True)
        row = row.reshape(-1)
        tp_track = uniq // max(m, 1)
        tp_plot = uniq % max(m, 1)
        p_track = np.bincount(row, weights=pred.w[pairs.comp] * p_pair, minlength=len(uniq))
        stats["gated_pairs"] = len(pairs)

        # 3. clutter density per track-plot row
        pdpg = np.full(ns, float(b.p_detection) * self.P_G)
        rho_plot = np.maximum(
            np.asarray(b.clutter_density, dtype=np.float64), cfg.clutter_density_floor
        )
        if cfg.clutter == "known":
            rho = rho_plot[tp_plot]
        else:
            m_trk = np.bincount(tp_track, minlength=ns)
            R_nom = b.R.mean(axis=0) if m else np.eye(self.k)
            Sc = HPH + R_nom
            _, y_bar, S_bar = comp.moment_match(pred.w, y, Sc, loc, ns)
            nu = b.z[tp_plot] - y_bar[tp_track]
            d2 = np.einsum("pi,pi->p", nu, np.linalg.solve(S_bar[tp_track], nu[..., None])[..., 0])
            m_trk = plots_in_track_gate(d2, tp_track, ns, self.g, m_trk)
            vol = gate_volume(S_bar, self.g) if ns else np.zeros(0)
            vol = np.maximum(vol, cfg.clutter_volume or 0.0)  # V_k reading, issue 16
            rho_trk = estimated_clutter_density(
                m_trk, pdpg, psi_det, vol, cfg.clutter_density_floor
            )
            rho = rho_trk[tp_track]

        # 4. association
        res = self._associate(psi_det, pdpg, tp_track, tp_plot, m, p_track, rho)
        for k_, v in res.stats.items():
            stats[k_] = v

        # 5. existence
        exist_post = self.chain.update(exist_pred, res.psi_post)

        # 6. components: children, Singer merge, pruning
        children = component_update(
            pred, loc, pairs, p_pair, row, p_track, res.beta0, res.beta, self.H, b.R, uid
        )
        merged = comp.singer_merge(children)
        stats["components_merged"] = len(merged)
        kept = comp.prune(merged, cfg.prune_threshold, cfg.max_components, self.n)
        others = np.flatnonzero(~inside[self.mix.track])
        self.mix = comp.Mixture.concat([self.mix.take(others), kept])
        stats["components"] = len(self.mix)
        if ns:
            x_sel, P_sel = comp.moment_match(
                kept.w, kept.x, kept.P, np.searchsorted(sel, kept.track), ns
            )[1:]
            self.x_out[sel] = x_sel
            self.P_out[sel] = P_sel
            self.exist[sel] = exist_post
            self.t_last[sel] = t_pred[sel]
        detected = (1.0 - res.beta0) > 0.5
        hit = sel[detected]
        self.updates[hit] += 1
        self.radar_mask[hit] |= bit
        self.last_update[hit] = t_pred[hit]
        assigned = np.full(self.n, -1, dtype=np.int64)
        if len(res.beta):
            order = np.lexsort((-res.beta, tp_track))
            first = np.r_[True, tp_track[order][1:] != tp_track[order][:-1]]
            best = order[first]
            good = res.beta[best] > res.beta0[tp_track[best]]
            assigned[sel[tp_track[best[good]]]] = tp_plot[best[good]]

        # 7. management. Duplicates first, so that an established track keeps its id:
        # tracks whose most likely plot of this batch is the same one
        has_plot = np.flatnonzero(assigned[sel] >= 0)
        a, c = shared_plot_pairs(has_plot, assigned[sel][has_plot])
        keep = np.ones(self.n, bool)
        if len(a):
            psi_all = self.existence()
            loser, winner = duplicates(
                sel[a], sel[c], self.x_out, self.P_out, psi_all, self.confirmed, self.g_dup
            )
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
        # confirmation of the surviving tracks (hysteresis: never revoked)
        psi_sel = self.chain.existence(self.exist[sel]) if ns else np.zeros(0)
        conf = to_confirm(
            psi_sel,
            self.confirmed[sel],
            self.updates[sel],
            cfg.tau_confirm,
            cfg.confirm_min_updates,
        )
        psi_now_sel = self.existence()
        for r in sel[conf & keep[sel]]:
            self.confirmed[r] = True
            events.append(
                TrackEventRecord(t_batch, "confirmed", int(self.ids[r]), float(psi_now_sel[r]))
            )
        # termination (existence predicted to the batch time for every track)
        psi_now = self.chain.existence(
            self.chain.predict(self.exist, np.maximum(t_batch - self.t_last, 0) * NS)
        )
        coasting = np.zeros(self.n, bool)
        if cfg.max_coast is not None:
            coasting = (t_batch - self.last_update) > round(cfg.max_coast / NS)
        term = (to_terminate(psi_now, cfg.tau_terminate) | coasting) & keep
        for r in np.flatnonzero(term & self.confirmed):
            events.append(
                TrackEventRecord(
                    t_batch,
                    "terminated",
                    int(self.ids[r]),
                    float(psi_now[r]),
                    reason="no plot for max_coast" if coasting[r] else "existence below tau_t",
                )
            )
        keep &= ~term
        stats["terminated"] = int(term.sum())
        if not keep.all():
            assigned = assigned[keep]
            self._remove(keep)

        # 8. initiation from plots no track selected
        used = np.zeros(m, bool)
        used[pairs.plot] = True
        free = np.flatnonzero(~used)
        new = self._initiate(b, free, plot_time, uid)
        assigned = np.concatenate([assigned, np.full(new, -1, dtype=np.int64)])
        stats["initiated"] = new
        for k_, v in stats.items():
            self._count(k_, v)

        x, P, psi = self._predict_out(t_batch)
        return TrackerOutput(
            time_ns=t_batch,
            radar_id=b.radar_id,
            ids=self.ids.copy(),
            states=x,
            covariances=P,
            existence=psi,
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

    def _associate(
        self,
        psi: np.ndarray,
        pdpg: np.ndarray,
        tp_track: np.ndarray,
        tp_plot: np.ndarray,
        m: int,
        p_track: np.ndarray,
        rho: np.ndarray,
    ) -> AssociationResult:
        kind = self.cfg.association
        if kind == "single":
            return single_target(psi, pdpg, tp_track, p_track / rho)
        if kind == "gnn":
            return gnn_association(psi, pdpg, tp_track, tp_plot, m, p_track / rho)
        rho_lm = modified_clutter_density(
            tp_track, tp_plot, m, p_track, rho, psi, pdpg, self.cfg.lm_prior_density
        )
        lm = single_target(psi, pdpg, tp_track, p_track / rho_lm)
        if kind == "lm":
            return lm
        return joint_association(
            psi, pdpg, tp_track, tp_plot, m, p_track / rho, self.cfg.jipda_max_events, lm
        )

    def _initiate(
        self, b: MeasurementBatch, free: np.ndarray, plot_time: np.ndarray, uid: np.ndarray
    ) -> int:
        cfg = self.cfg
        if cfg.initiation == "none" or len(free) == 0:
            return 0
        z, R, t = b.z[free], b.R[free], plot_time[free]
        before = self.n
        if cfg.initiation == "one_point":
            x, P = one_point(z, R, cfg.v_max)
            self._add_tracks(x, P, t, uid[free])
        else:
            # drop expired buffered plots, pair, consume the paired ones, buffer the rest
            t_now = int(b.time_ns)
            self.buffer.keep((t_now - self.buffer.time) * NS <= cfg.init_max_dt)
            old, new, dt = pair_plots(
                self.buffer, z, t, cfg.v_max, cfg.init_min_dt, cfg.init_max_dt
            )
            if len(old):
                x, P = two_point(self.buffer.z[old], self.buffer.R[old], z[new], R[new], dt)
                self._add_tracks(x, P, t[new], uid[free][new])
                consumed = np.zeros(len(self.buffer), bool)
                consumed[old] = True
                self.buffer.keep(~consumed)
            self.buffer.add(z, R, t, uid[free])
        return self.n - before
