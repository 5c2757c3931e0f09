"""Global-nearest-neighbour (GNN) multi-target tracker: the baseline of spec 01 §6-7.

Per scan (all plots of one antenna revolution, converted to the system frame):

1. predict every track to the scan time (one common time per scan: the baseline's
   simplification);
2. gate all track × plot pairs (:func:`fusion.association.gating.gate`, chi-square gate
   from P_G and the measurement dimension, cheap box pre-gate);
3. cost d² + ln det S (003 eq. 20) with the IMM's mode-mixed prediction, or with one
   matrix per mode (``imm_gating="per-mode"``: valid if inside any mode's gate, cost the
   smallest mode cost), "no assignment" at the gate-edge cost G + ln det S_i
   (so any gated plot beats leaving the track empty), independent clusters solved by the
   auction algorithm (default) or scipy's Jonker-Volgenant — same optimum;
4. update assigned tracks; life cycle (003: update, initialise, delete): unassigned plots
   start tentative tracks (one-point initiation); a tentative track is confirmed with M
   hits in its first N scans (M-of-N) and deleted when that can no longer happen; a
   confirmed track is deleted after ``max_misses`` consecutive misses.

The filter is any object with the :class:`fusion.filters.ModelFilter` / :class:`IMM`
interface (``initiate``, ``predict``, ``predict_measurement``, ``update``, ``position``);
the state of all tracks is one batched filter state.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..filters import IMM, GaussianState, IMMState
from .assignment import assign_auction, assign_jv, assign_sparse
from .gating import GatedPairs, gate, gate_threshold

TENTATIVE, CONFIRMED = 0, 1


@dataclass(frozen=True)
class GNNConfig:
    p_gate: float = 0.9997
    confirm_m: int = 2
    confirm_n: int = 3
    max_misses: int = 3
    solver: str = "auction"
    velocity_sigma: float = 350.0
    acceleration_sigma: float = 10.0
    imm_gating: str = "mixed"

    def __post_init__(self) -> None:
        if self.imm_gating not in ("mixed", "per-mode"):
            raise ValueError(f"imm_gating = {self.imm_gating!r}: must be 'mixed' or 'per-mode'")
        if self.solver not in ("auction", "jv"):
            raise ValueError(f"solver = {self.solver!r}: must be 'auction' or 'jv'")
        if not 1 <= self.confirm_m <= self.confirm_n:
            raise ValueError(
                f"confirm_m = {self.confirm_m}, confirm_n = {self.confirm_n}: need 1 <= M <= N"
            )
        if self.max_misses < 1:
            raise ValueError(f"max_misses = {self.max_misses}: must be >= 1")


@dataclass
class ScanReport:
    """What happened in one scan: track ids and their assigned plot (−1: none)."""

    time: float
    track_ids: np.ndarray
    assigned_plot: np.ndarray
    born: list[int] = field(default_factory=list)
    confirmed: list[int] = field(default_factory=list)
    deleted: list[int] = field(default_factory=list)
    n_gated_pairs: int = 0


class GNNTracker:
    """GNN tracker over a batched filter. ``filt``: ModelFilter or IMM."""

    def __init__(self, filt, config: GNNConfig | None = None) -> None:
        self.filt = filt
        self.cfg = config or GNNConfig()
        self._solve = assign_auction if self.cfg.solver == "auction" else assign_jv
        self.state = None
        self.ids = np.zeros(0, int)
        self.status = np.zeros(0, int)
        self.hits = np.zeros(0, int)
        self.age = np.zeros(0, int)  # scans since birth (birth scan = 1)
        self.misses = np.zeros(0, int)
        self.time: float | None = None
        self._next_id = 0

    def __len__(self) -> int:
        return self.ids.size

    # --- state helpers -----------------------------------------------------------------
    def _concat(self, a, b):
        if a is None or len(a) == 0:
            return b
        return (IMMState if isinstance(self.filt, IMM) else GaussianState).concat([a, b])

    def _keep(self, mask):
        self.state = self.state.take(np.flatnonzero(mask)) if self.state is not None else None
        for name in ("ids", "status", "hits", "age", "misses"):
            setattr(self, name, getattr(self, name)[mask])

    def estimates(self) -> GaussianState:
        """Current estimates of all tracks (IMM: combined, common format)."""
        if isinstance(self.filt, IMM):
            return self.filt.estimate(self.state)
        return self.state

    def positions(self) -> np.ndarray:
        if self.state is None or len(self.state) == 0:
            return np.zeros((0, 2))
        return self.filt.position(self.state)

    @staticmethod
    def _gate_per_mode(per_mode, z, R, G, Rbar):
        """IMM with one association matrix per mode (spec 01 §6 [S], 003): a pair is valid
        if it is inside any mode's gate; its cost is the smallest mode cost
        d²_j + ln det S_j; the miss cost is the largest mode's gate-edge cost."""
        results = [gate(zj, Sj, z, R, G) for zj, Sj in per_mode]
        n = results[0].n_states
        k = results[0].n_plots
        track = np.concatenate([r.state for r in results])
        plot = np.concatenate([r.plot for r in results])
        d2 = np.concatenate([r.d2 for r in results])
        logdet = np.concatenate([r.logdet for r in results])
        order = np.lexsort((d2 + logdet, plot, track))
        key = track[order] * max(k, 1) + plot[order]
        first = np.ones(order.size, bool)
        first[1:] = key[1:] != key[:-1]
        keep = order[first]
        nu = np.concatenate([r.nu for r in results])[keep]
        S = np.concatenate([r.S for r in results])[keep]
        npre = sum(r.n_pregated for r in results)
        g = GatedPairs(track[keep], plot[keep], nu, S, d2[keep], logdet[keep], n, k, npre)
        miss = G + np.max([np.linalg.slogdet(Sj + Rbar)[1] for _, Sj in per_mode], axis=0)
        return g, miss

    # --- one scan ----------------------------------------------------------------------
    def step(self, z: np.ndarray, R: np.ndarray, time_s: float) -> ScanReport:
        """Process the plots of one scan: z (k, m), R (k, m, m) in the system frame, all
        taken at ``time_s`` seconds: predict, gate and assign, update, then the life cycle
        (confirm, delete) and initiation from the unassigned plots."""
        z = np.asarray(z, float).reshape(-1, np.shape(z)[-1] if np.ndim(z) == 2 else 2)
        k, m = z.shape
        R = np.asarray(R, float).reshape(k, m, m)
        n = self.ids.size
        assigned_plot, n_gated = np.full(n, -1), 0
        if n:
            assigned_plot, n_gated = self._assign_and_update(z, R, time_s)
        report = ScanReport(time_s, self.ids.copy(), assigned_plot.copy(), n_gated_pairs=n_gated)
        if n:
            self._life_cycle(report)
        used = np.zeros(k, bool)
        used[assigned_plot[assigned_plot >= 0]] = True
        free = np.flatnonzero(~used)
        if free.size:
            report.born = self._initiate(z[free], R[free])
        self.time = time_s
        return report

    def _assign_and_update(self, z: np.ndarray, R: np.ndarray, time_s: float):
        """Predict every track to ``time_s``, gate, assign (one plot per track) and update
        the assigned tracks; returns (assigned plot per track or −1, gated pairs)."""
        k, m = z.shape
        n = self.ids.size
        assigned_plot = np.full(n, -1)
        self.state = self.filt.predict(self.state, time_s - self.time)
        pred = self.filt.predict_measurement(self.state, np.zeros((n, m, m)))
        G = gate_threshold(self.cfg.p_gate, m)
        # miss cost: the gate-edge cost with the track's own S (plot R at its mean)
        Rbar = R.mean(axis=0) if k else np.zeros((m, m))
        if isinstance(self.filt, IMM) and self.cfg.imm_gating == "per-mode":
            g, miss = self._gate_per_mode(pred[2], z, R, G, Rbar)
        else:
            g = gate(pred[0], pred[1], z, R, G)
            miss = G + np.linalg.slogdet(pred[1] + Rbar)[1]
        rows = assign_sparse(g.state, g.plot, g.cost, miss, n, k, self._solve)
        assigned_plot[rows >= 0] = g.plot[rows[rows >= 0]]
        upd = np.flatnonzero(assigned_plot >= 0)
        if upd.size:
            sub = self.state.take(upd)
            out = self.filt.update(sub, z[assigned_plot[upd]], R[assigned_plot[upd]])
            self.state.put(upd, out[0])
        hit = assigned_plot >= 0
        self.age += 1
        self.hits += hit
        self.misses = np.where(hit, 0, self.misses + 1)
        return assigned_plot, len(g)

    def _life_cycle(self, report: ScanReport) -> None:
        """M-of-N confirmation, deletion of hopeless tentative and lost confirmed tracks."""
        cfg = self.cfg
        newly = (self.status == TENTATIVE) & (self.hits >= cfg.confirm_m)
        self.status[newly] = CONFIRMED
        report.confirmed = self.ids[newly].tolist()
        hopeless = (self.status == TENTATIVE) & (
            self.hits + np.maximum(cfg.confirm_n - self.age, 0) < cfg.confirm_m
        )
        lost = (self.status == CONFIRMED) & (self.misses >= cfg.max_misses)
        dead = hopeless | lost
        report.deleted = self.ids[dead].tolist()
        self._keep(~dead)

    def _initiate(self, z: np.ndarray, R: np.ndarray) -> list[int]:
        """New tentative tracks from the unassigned plots ``z``, ``R``; their ids."""
        new = self.filt.initiate(
            z,
            R,
            velocity_sigma=self.cfg.velocity_sigma,
            acceleration_sigma=self.cfg.acceleration_sigma,
        )
        count = len(z)
        self.state = self._concat(self.state, new)
        ids = np.arange(self._next_id, self._next_id + count)
        self._next_id += count
        self.ids = np.concatenate([self.ids, ids])
        self.status = np.concatenate([self.status, np.full(count, TENTATIVE)])
        self.hits = np.concatenate([self.hits, np.ones(count, int)])
        self.age = np.concatenate([self.age, np.ones(count, int)])
        self.misses = np.concatenate([self.misses, np.zeros(count, int)])
        return ids.tolist()
