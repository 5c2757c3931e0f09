"""IMM mixture track density: every ITS component is an IMM (IMM-IPDA, IMM-ITS,
IMM-LM-ITS, IMM-JITS): the IMM of [Dikić] (eq. 15-21) inside the ITS components of
[thesis] ch. 5-6 (docs/reports/tracker-log.md, "IMM inside the existence trackers").

Each component c of a track carries a weight ξ^c, a plot history h^c (Singer N-scan
memory, depth 0 = one IMM per track) and, per mode j, a mode probability μ^c_j and a
mode-matched Gaussian (x̂^c_j, P^c_j) in that mode's own state (CV [x, vx, y, vy(, z, vz)],
coordinated turn (x, y, ψ, ω, v(, z, vz)) or Singer [x, vx, ax, …]). The existence
recursion and the association are unchanged: they only see the track likelihoods p^τ_i.

Per batch, for the components of the tracks in coverage over their dt:

1. **Interaction** (eq. 15-17, :func:`fusion.filters.imm_interaction.interact`, the one
   IMM interaction of skyfuse): Π(dt) = Π_T^{dt/T} (the configured mode transition matrix
   Π_T per period T, fractional power by eigendecomposition); c_j = Σ_i Π_ij μ_i,
   μ_{i|j} = Π_ij μ_i / c_j, x̂⁰_j, P⁰_j = moment match of the modes with μ_{·|j} in the
   common Singer layout (the conversions of [Dikić] eq. 22), converted back to mode j.
2. **Mode-matched prediction** of every mode (KF or EKF, :func:`fusion.filters.ekf.predict`).
   **Long coasts** [IMPL] (docs/reports/tracker-log.md, "Re-identification, held existence and
   straight coasts"): a component predicted over dt > ``coast_after``
   (a track outside every radar's coverage, in a cone of silence, or missed for several
   scans) is predicted in ⌈dt / coast_step⌉ equal steps, and afterwards every
   manoeuvre mode takes the CV mode's prediction (converted to its layout, eq. 22):
   a lost aircraft is assumed to fly straight, as the output model and the
   re-identification assume. In one step the discrete models' noise lets a single
   piecewise-constant acceleration act for the whole gap (σ_pos = √q dt²/2, ≈ 10 km
   for q = 4 m²/s⁴ over 100 s), and the turn mode's turn-rate noise (σ_ω ≈ 0.3 rad/s
   after 100 s) linearised over it gave σ_pos ≈ 150 km on the Barcelona recording;
   such a gate holds other aircraft's plots, which then count as detections at full
   P_D, erode the track and let it take another aircraft on emergence. Shorter dt (a
   track seen every scan) are predicted as before, in one step.
3. **Likelihoods**: a plot is gated by a component if any mode's gate holds it (the
   per-model gating of [MZD]; ``gating = "mixed"``: if the gate of the component's
   mode-mixed prediction holds it); p^c_i = Σ_j c_j N(z_i; H x̂_j, H P_j Hᵀ + R_i) / P_G
   (eq. 18, 4.17), p^τ_i = Σ_c ξ^c p^c_i (5.10). **Reachability** [IMPL]
   (:mod:`.reach_gate`, eq. C1): a pair whose plot is farther from the track's last fix
   than v_max times the time since, plus √g times the largest σ of the fix and of the
   plot, is dropped first.
4. **Update**: the "no plot" child keeps the predicted modes with μ = c; the child of plot
   i has every mode Kalman-updated (Joseph form) and μ_j ∝ c_j N_j(z_i) (eq. 19), weight
   ξ^{c,i} = β_i ξ^c p^c_i / p^τ_i (5.15). The Singer merge moment-matches each mode of the
   components with equal history with weights ξ μ_j (their mode probabilities become
   Σ ξ μ_j / Σ ξ); pruning as for the Gaussian mixture.
5. **Estimate** (eq. 20-21, 4.66-4.68): all modes of all components of a track
   moment-matched in the common layout, returned in the CV layout (m, m/s).

Late plots (:class:`~.base.Retrodiction`): every mode of every component retrodicted with
its own model and the track's last prior of that mode (Bar-Shalom 2002, A1,
:mod:`fusion.tracker.oosm`), without mode interaction over the lag (:meth:`retrodict`).

State: the components in a slot store (:mod:`fusion.tracker.component_slots`); the
track estimates and the reachability gate's fixes are columns of the track store
(:mod:`fusion.tracker.store`).

With one CV mode and Π = [[1]] every step reduces to the Gaussian-mixture density (IPDA /
ITS); the tests check that equivalence and the mode probabilities of a two-model case.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from skyfuse.fusion.association.gating import gate
from skyfuse.fusion.filters.ekf import predict as ekf_predict
from skyfuse.fusion.filters.imm_interaction import interact, same_layout
from skyfuse.fusion.filters.initiation import embed_common
from skyfuse.fusion.filters.kalman import update_with_innovation
from skyfuse.fusion.filters.moment_matching import (
    moment_match,
    moment_match_rows,
    moment_match_rows_each,
)
from skyfuse.fusion.models import ConstantVelocity, CoordinatedTurn, Singer
from skyfuse.fusion.models.conversions import from_common, to_common, to_cv_layout
from skyfuse.schemas.snapshot import entry, mapping

from ..component_slots import ComponentSlots
from ..components import history_groups, prune_indices
from ..its import shift_history
from ..oosm import oosm_update, retrodict
from .base import GatedTable, estimate_group, gate_probability_of
from .gaussian_mixture import MixturePrediction, track_table
from .imm_likelihood_kernel import mode_pair_likelihoods
from .reach_gate import ReachGate, largest_sigma


class ModeTransition:
    """Mode transition probabilities over any dt: Π(dt) = Π_T^{dt/T} (rows: from, columns:
    to), from a row-stochastic ``tpm`` per ``period`` s with real non-negative eigenvalues."""

    def __init__(self, tpm, period: float) -> None:
        tpm = np.asarray(tpm, dtype=np.float64)
        r = len(tpm)
        if tpm.shape != (r, r) or (tpm < 0).any() or not np.allclose(tpm.sum(axis=1), 1.0):
            raise ValueError(f"mode transition matrix {tpm.tolist()}: must be row-stochastic")
        lam, V = np.linalg.eig(tpm)
        if np.abs(lam.imag).max() > 1e-12 or (lam.real < -1e-12).any():
            raise ValueError(
                f"mode transition matrix eigenvalues {lam}: must be real and non-negative "
                "so that fractional periods are defined"
            )
        self.tpm, self.period = tpm, float(period)
        self._lam = np.clip(lam.real, 0.0, None)
        self._V = np.ascontiguousarray(V.real)  # (a view of the complex array otherwise)
        self._Vinv = np.linalg.inv(self._V)

    @property
    def r(self) -> int:
        return len(self.tpm)

    def __call__(self, dt: np.ndarray) -> np.ndarray:
        """Π(dt) for dt (n,) seconds, shape (n, r, r): V diag(λ^{dt/T}) V⁻¹, negative
        rounding clipped to 0, rows renormalised (one compiled loop over the n)."""
        t = np.maximum(np.asarray(dt, dtype=np.float64), 0.0) / self.period
        return _fractional_powers(self._V, self._lam, self._Vinv, np.ascontiguousarray(t))


@numba.njit(cache=True, nogil=True)
def _fractional_powers(V, lam, Vinv, t):
    """Row-stochastic V diag(λ^t_k) V⁻¹ (n, r, r) for the exponents t (n,)."""
    n, r = len(t), len(lam)
    out = np.empty((n, r, r))
    p = np.empty(r)
    for k in range(n):
        for j in range(r):
            p[j] = lam[j] ** t[k]
        for a in range(r):
            tot = 0.0
            for b in range(r):
                m = 0.0
                for j in range(r):
                    m += V[a, j] * p[j] * Vinv[j, b]
                m = max(m, 0.0)
                out[k, a, b] = m
                tot += m
            for b in range(r):
                out[k, a, b] /= tot
    return out


@dataclass
class IMMComponents:
    """Flat store of IMM components: track (C,), w (C,), hist (C, N), mu (C, r), and per
    mode j: x[j] (C, d_j), P[j] (C, d_j, d_j)."""

    track: np.ndarray
    w: np.ndarray
    hist: np.ndarray
    mu: np.ndarray
    x: list[np.ndarray]
    P: list[np.ndarray]

    def __len__(self) -> int:
        return len(self.w)

    def take(self, idx: np.ndarray) -> IMMComponents:
        return IMMComponents(
            self.track[idx],
            self.w[idx],
            self.hist[idx],
            self.mu[idx],
            [a[idx] for a in self.x],
            [a[idx] for a in self.P],
        )

    @staticmethod
    def concat(parts: list[IMMComponents]) -> IMMComponents:
        r = len(parts[0].x)
        return IMMComponents(
            np.concatenate([p.track for p in parts]),
            np.concatenate([p.w for p in parts]),
            np.concatenate([p.hist for p in parts]),
            np.concatenate([p.mu for p in parts]),
            [np.concatenate([p.x[j] for p in parts]) for j in range(r)],
            [np.concatenate([p.P[j] for p in parts]) for j in range(r)],
        )


class IMMPrediction(MixturePrediction):
    """Predicted IMM components of ``rows``: comp (mu = c, the predicted mode
    probabilities), loc (C,) index into rows, per-mode predicted measurements
    y (C, r, k) and H P Hᵀ (C, r, k, k); z_mean, S0 from the mode-mixed (eq. 20-21)
    component predictions, on first use."""

    def __init__(self, rows, comp: IMMComponents, loc, y, HPH, since=None) -> None:
        super().__init__(rows, comp.w, loc, y, HPH)
        self.comp = comp
        self.since = since  # (s,) time since each row's fix (ReachGate); None: no gate

    def _track_moments(self) -> tuple[np.ndarray, np.ndarray]:
        if self._moments is None:
            yc, Sc = moment_match_rows(self.comp.mu, self.y, self.HPH)
            _, z, S = moment_match(self.w, yc, Sc, self.loc, len(self.rows))
            self._moments = (z, S)
        return self._moments


class IMMRetrodiction(IMMPrediction):
    """Retrodicted IMM components of late tracks (what ``likelihoods`` gates, without the
    reachability gate) and what the out-of-sequence update needs: the current components
    ``current`` and the cross terms ``cross[j]`` of each mode (O1-O4)."""

    def __init__(self, rows, comp, loc, y, HPH, *, current, cross) -> None:
        super().__init__(rows, comp, loc, y, HPH)
        self.current, self.cross = current, cross


@dataclass
class IMMTable(GatedTable):
    """Track × plot table plus the (component, plot) pairs behind it: pair_comp, pair_plot
    (P,), per-mode innovations nu (P, r, k), S (P, r, k, k), log N (P, r); p_pair (P,)
    p^c_i; pair_row (P,) table row; R (m, k, k); uid (m,) plot history ids."""

    pair_comp: np.ndarray | None = None
    pair_plot: np.ndarray | None = None
    nu: np.ndarray | None = None
    S: np.ndarray | None = None
    log_n: np.ndarray | None = None
    p_pair: np.ndarray | None = None
    pair_row: np.ndarray | None = None
    R: np.ndarray | None = None
    uid: np.ndarray | None = None


class IMMMixtureDensity:
    """IMM components of all tracks (see the module docstring).

    models: the r mode models (CV, CoordinatedTurn, Singer; position-measured);
    transition: :class:`ModeTransition`; mu0 (r,): mode probabilities of new tracks;
    init_acceleration: σ (m/s²) of the zero acceleration of new tracks in the common
    layout; ndim: 2 or 3; depth, prune_threshold, max_components as the Gaussian mixture;
    gating: ``per-mode`` (a plot is gated if any mode's gate holds it, [MZD] §5) or
    ``mixed`` (the gate of each component's mode-mixed prediction, eq. 20-21 over c);
    coast_after, coast_step: the long coasts of step 2; reach_speed: v_max of the
    reachability gate (:mod:`.reach_gate`), None: off."""

    late_plots = "retrodict"

    def __init__(
        self,
        models: list,
        transition: ModeTransition,
        mu0,
        ndim: int,
        depth: int = 0,
        prune_threshold: float = 1e-3,
        max_components: int = 30,
        init_acceleration: float = 5.0,
        coast_after: float | None = None,
        coast_step: float = 10.0,
        reach_speed: float | None = None,
        gating: str = "per-mode",
    ) -> None:
        if transition.r != len(models):
            raise ValueError(f"{len(models)} modes but a {transition.r}-mode transition matrix")
        if gating not in ("per-mode", "mixed"):
            raise ValueError(f"gating = {gating!r}: must be 'per-mode' or 'mixed'")
        self.models = list(models)
        self.transition = transition
        self.mu0 = np.asarray(mu0, dtype=np.float64) / np.sum(mu0)
        self.ndim = ndim
        self.dim = 2 * ndim
        self.depth = depth
        self.prune_threshold = prune_threshold
        self.max_components = max_components
        self.init_acceleration = init_acceleration
        self.coast_after = coast_after
        self.coast_step = coast_step
        self.reach = ReachGate(reach_speed, ndim)
        self.gating = gating
        self.H = [m.H() for m in self.models]
        self.pos = [np.array(m.position_index) for m in self.models]
        self.mode_dims = tuple(m.dim for m in self.models)
        self.same_layout = same_layout(self.models)
        r = len(self.models)
        self.slots = ComponentSlots(
            IMMComponents(
                np.zeros(0, np.int64),
                np.zeros(0),
                np.zeros((0, depth), np.int64),
                np.zeros((0, r)),
                [np.zeros((0, m.dim)) for m in self.models],
                [np.zeros((0, m.dim, m.dim)) for m in self.models],
            )
        )
        self.tracks = None
        self.stats: dict[str, int] = {}
        self._next_uid = 1

    @property
    def r(self) -> int:
        return len(self.models)

    def __len__(self) -> int:
        return len(self.tracks)

    @property
    def comp(self) -> IMMComponents:
        """Every component of every track (a copy of the live slots, in store order)."""
        return self.slots.live()

    # ------------------------------------------------------------------ layouts
    def _common(self, j: int, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (x, P) if self.same_layout else to_common(self.models[j], x, P)

    def _native(self, j: int, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (x, P) if self.same_layout else from_common(self.models[j], x, P)

    # ------------------------------------------------------------------ tracks
    def attach(self, tracks) -> None:
        """Columns ``x`` (n, d), ``P`` (n, d, d): the track estimates (eq. 20-21, CV
        layout); the reachability gate's columns when it is on; new tracks get one IMM
        component (:meth:`_appended`)."""
        tracks.declare(estimate_group(self.dim, self._appended, self._kept))
        self.reach.attach(tracks)
        self.tracks = tracks

    def _kept(self, mask: np.ndarray) -> None:
        self.slots.keep(mask)

    def _appended(self, rows: np.ndarray, new) -> None:
        """New tracks from CV-layout Gaussians: each mode gets the state converted from the
        common layout (accelerations 0 ± init_acceleration)."""
        x, P, nn = new.x, new.P, len(rows)
        if self.same_layout and isinstance(self.models[0], ConstantVelocity):
            xs, Ps = [x.copy()] * self.r, [P.copy()] * self.r
        else:
            xc, Pc = embed_common(x, P, self.ndim, self.init_acceleration, (1e8, 1e4))
            # a CV mode gets back exactly the CV entries it was embedded from
            sym = 0.5 * (P + P.swapaxes(1, 2))
            conv = [
                (x.copy(), sym.copy())
                if isinstance(m, ConstantVelocity) and m.ndim == x.shape[1] // 2
                else from_common(m, xc, Pc)
                for m in self.models
            ]
            xs, Ps = [a for a, _ in conv], [b for _, b in conv]
        new = IMMComponents(
            rows,
            np.ones(nn),
            np.zeros((nn, self.depth), np.int64),
            np.broadcast_to(self.mu0, (nn, self.r)).copy(),
            xs,
            Ps,
        )
        self.slots.append(new)

    # ------------------------------------------------------------------ predict
    def _interact(self, comp: IMMComponents, dt: np.ndarray) -> IMMComponents:
        """Mixing (eq. 15-17) and mode-matched prediction; returns mu = c."""
        x0, P0, c = interact(comp.mu, self.transition(dt), comp.x, comp.P, self.models)
        xs, Ps = [], []
        for j, model in enumerate(self.models):
            xj, Pj = self._predict_mode(model, x0[j], P0[j], dt)
            xs.append(xj)
            Ps.append(Pj)
        self._straight_coast(xs, Ps, dt)
        return IMMComponents(comp.track, comp.w, comp.hist, c, xs, Ps)

    def _straight_coast(self, xs: list, Ps: list, dt: np.ndarray) -> None:
        """Components coasting longer than ``coast_after``: every manoeuvre mode takes
        the CV mode's prediction (module docstring, step 2)."""
        cv_first = isinstance(self.models[0], ConstantVelocity)
        if self.coast_after is None or self.r == 1 or not cv_first:
            return
        long = np.flatnonzero(dt > self.coast_after)
        if len(long) == 0:
            return
        xc, Pc = self._common(0, xs[0][long], Ps[0][long])
        for j in range(1, self.r):
            xs[j][long], Ps[j][long] = self._native(j, xc, Pc)

    def _predict_mode(
        self, model, x: np.ndarray, P: np.ndarray, dt: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Mode-matched prediction over dt (C,) s, in ⌈dt / coast_step⌉ equal steps for
        the components that coast longer than ``coast_after`` (module docstring, step 2)."""
        if self.coast_after is None or len(dt) == 0 or dt.max() <= self.coast_after:
            return ekf_predict(model, x, P, dt)
        steps = np.where(dt > self.coast_after, np.ceil(dt / self.coast_step), 1.0)
        h = dt / steps
        x, P = ekf_predict(model, x, P, h)
        for s in range(1, int(steps.max())):
            rows = np.flatnonzero(steps > s)
            x[rows], P[rows] = ekf_predict(model, x[rows], P[rows], h[rows])
        return x, P

    def predict(self, rows: np.ndarray, dt: np.ndarray) -> IMMPrediction:
        # every component (one sensor seeing all tracks): views, no copy
        comp, loc = self.slots.rows(rows, len(self))
        dt = np.asarray(dt, dtype=np.float64)
        self.reach.predict(rows, dt)
        pred = self._interact(comp, dt[loc])
        y = np.stack([pred.x[j][:, self.pos[j]] for j in range(self.r)], axis=1)
        HPH = np.stack(
            [pred.P[j][:, p[:, None], p[None, :]] for j, p in enumerate(self.pos)], axis=1
        )
        return IMMPrediction(rows, pred, loc, y, HPH, self.reach.since(rows))

    # ------------------------------------------------------------------ likelihoods
    def likelihoods(self, pred: IMMPrediction, z: np.ndarray, R: np.ndarray, g: float) -> IMMTable:
        """Union of the modes' gates per component; p^c_i = Σ_j c_j N_j / P_G."""
        m, k = z.shape
        uid = self._next_uid + np.arange(m, dtype=np.int64)
        self._next_uid += m
        C, r = pred.y.shape[:2]
        y, HPH, per = pred.y.reshape(C * r, k), pred.HPH.reshape(C * r, k, k), r
        if self.gating == "mixed":  # one gate per component: its mode-mixed prediction
            (y, HPH), per = moment_match_rows(pred.comp.mu, pred.y, pred.HPH), 1
        g_pairs = gate(y, HPH, z, R, g)
        key = np.unique((g_pairs.state // per) * max(m, 1) + g_pairs.plot)
        pc, pp = key // max(m, 1), key % max(m, 1)
        if pred.since is not None and len(pp):
            sigma_z = largest_sigma(R)[pp]  # once per plot, not per pair
            reachable = self.reach.reachable(
                pred.rows[pred.loc[pc]], pred.since[pred.loc[pc]], z[pp], sigma_z, g
            )
            pc, pp = pc[reachable], pp[reachable]
        c = np.ascontiguousarray
        nu, S, log_n, mix = mode_pair_likelihoods(
            pc, pp, c(pred.y), c(pred.HPH), c(z, dtype=np.float64), c(R, dtype=np.float64),
            c(pred.comp.mu),
        )  # fmt: skip
        p_pair = mix / gate_probability_of(float(g), k)
        tp_track, tp_plot, p_track, row = track_table(pred.loc, pc, pp, pred.comp.w, p_pair, m)
        return IMMTable(tp_track, tp_plot, p_track, pc, pp, nu, S, log_n, p_pair, row, R, uid)

    # ------------------------------------------------------------------ update
    def _children(
        self, pred: IMMPrediction, t: IMMTable, beta0: np.ndarray, beta: np.ndarray
    ) -> IMMComponents:
        """Null child (μ = c) and one child per gated plot with every mode updated."""
        comp = pred.comp
        null = IMMComponents(
            comp.track, comp.w * beta0[pred.loc], _no_plot(comp.hist), comp.mu, comp.x, comp.P
        )
        if not (null.w > 0.0).all():  # children of weight 0 are dropped
            null = null.take(np.flatnonzero(null.w > 0.0))
        if len(t.pair_comp) == 0:
            return null
        c, p = t.pair_comp, t.pair_plot
        w = comp.w[c] * beta[t.pair_row] * t.p_pair / t.p[t.pair_row]
        # children of weight 0 (GNN: every pair but the chosen one) are dropped by the
        # update: no Kalman update for them
        live = np.flatnonzero(w > 0.0)
        if len(live) == 0:
            return null
        c, p, w, log_n, S, nu = c[live], p[live], w[live], t.log_n[live], t.S[live], t.nu[live]
        lw = log_n + np.log(np.maximum(comp.mu[c], 1e-300))
        mu = np.exp(lw - lw.max(axis=1, keepdims=True))
        mu /= mu.sum(axis=1, keepdims=True)  # eq. 19
        xs, Ps = [], []
        for j in range(self.r):
            xj, Pj = update_with_innovation(
                comp.x[j][c], comp.P[j][c], self.H[j], S[:, j], nu[:, j], t.R[p]
            )
            xs.append(xj)
            Ps.append(Pj)
        upd = IMMComponents(comp.track[c], w, shift_history(comp.hist[c], t.uid[p]), mu, xs, Ps)
        return IMMComponents.concat([null, upd])

    def _merge(self, comp: IMMComponents) -> IMMComponents:
        """Singer N-scan merge of IMM components: per mode, moment matching with weights
        ξ μ_j; merged μ_j = Σ ξ μ_j / Σ ξ."""
        if len(comp) == 0:
            return comp
        if np.bincount(comp.track).max() == 1:
            # one child per track (GNN; no plot gated): in track order every child is
            # its own group; the moment matching would copy it (P symmetrised) and give
            # the same μ_j = ξ μ_j / Σ_j ξ μ_j as below
            comp = comp.take(np.argsort(comp.track, kind="stable"))
            Ps = [0.5 * (P + P.swapaxes(1, 2)) for P in comp.P]
            return IMMComponents(
                comp.track, comp.w, comp.hist, self._merged_mu(comp.w[:, None] * comp.mu),
                comp.x, Ps,
            )  # fmt: skip
        inv, uniq = history_groups(comp.track, comp.hist)
        G = len(uniq)
        W = np.bincount(inv, weights=comp.w, minlength=G)
        xs, Ps, mass = [], [], []
        for j in range(self.r):
            wj = comp.w * comp.mu[:, j]
            Wj, xj, Pj = moment_match(wj, comp.x[j], comp.P[j], inv, G)
            xs.append(xj)
            Ps.append(Pj)
            mass.append(Wj)
        mu = self._merged_mu(np.column_stack(mass))
        return IMMComponents(uniq[:, 0].copy(), W, uniq[:, 1:].copy(), mu, xs, Ps)

    def _merged_mu(self, mass: np.ndarray) -> np.ndarray:
        """μ_j = Σ ξ μ_j / Σ_j Σ ξ μ_j from the merged masses (G, r); uniform where 0."""
        tot = mass.sum(axis=1, keepdims=True)
        return np.where(tot > 0, mass / np.where(tot > 0, tot, 1.0), 1.0 / self.r)

    def update(
        self, pred: IMMPrediction, table: IMMTable, beta0: np.ndarray, beta: np.ndarray
    ) -> None:
        children = self._children(pred, table, beta0, beta)  # all of weight > 0
        self.store_children(pred.rows, children, len(table.pair_comp))
        hit = pred.rows[beta0 < 0.5]
        self.reach.fix(hit, self.tracks.x[hit], self.tracks.P[hit])

    def store_children(self, rows: np.ndarray, children: IMMComponents, pairs: int) -> None:
        """Merge and prune the updated components ``children`` of the tracks ``rows``
        (sorted), which replace their components; track estimates (eq. 20-21). Also the
        out-of-sequence update's last step (:meth:`update_late`), whose children may
        carry weight 0 (dropped here)."""
        positive = children.w > 0.0
        if not positive.all():
            children = children.take(np.flatnonzero(positive))
        merged = self._merge(children)
        keep, w = prune_indices(
            merged.track, merged.w, self.prune_threshold, self.max_components, len(self)
        )
        kept = merged.take(keep)
        kept.w = w
        self.slots.replace_rows(rows, len(self), kept)
        self.stats = {
            "gated_pairs": pairs,  # (component, plot) pairs
            "components_merged": len(merged),
            "components": len(self.slots),
        }
        x, P = self._track_estimates(kept, np.searchsorted(rows, kept.track), len(rows))
        self.tracks.x[rows] = x
        self.tracks.P[rows] = P

    def _track_estimates(
        self, comp: IMMComponents, loc: np.ndarray, ngroups: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """eq. 20-21 over modes and components at once, in the CV layout."""
        if self.same_layout and isinstance(self.models[0], ConstantVelocity):
            xc = np.stack(comp.x, axis=1)
            Pc = np.stack(comp.P, axis=1)
        else:
            # the moments of the CV entries of the common layout need only those entries
            pairs = [to_cv_layout(m, comp.x[j], comp.P[j]) for j, m in enumerate(self.models)]
            xc = np.stack([a for a, _ in pairs], axis=1)
            Pc = np.stack([b for _, b in pairs], axis=1)
        C, r, dc = xc.shape
        if C == ngroups and (C < 2 or (loc[1:] > loc[:-1]).all()):
            # one component per track (GNN, IPDA, JIPDA): the modes of each row
            return moment_match_rows(comp.w[:, None] * comp.mu, xc, Pc)
        w = (comp.w[:, None] * comp.mu).reshape(-1)
        _, x, P = moment_match(
            w, xc.reshape(C * r, dc), Pc.reshape(C * r, dc, dc), np.repeat(loc, r), ngroups
        )
        return x, P

    def estimate(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.tracks.x[rows].copy(), self.tracks.P[rows].copy()

    def estimates_view(self) -> tuple[np.ndarray, np.ndarray]:
        """x (n, dim), P (n, dim, dim) of all tracks, not copied: read only."""
        return self.tracks.x, self.tracks.P

    def mode_probabilities(self, rows: np.ndarray) -> np.ndarray:
        """Track-level mode probabilities Σ_c ξ^c μ^c (s, r) of ``rows``."""
        comp = self.slots.live()
        out = np.zeros((len(self), self.r))
        np.add.at(out, comp.track, comp.w[:, None] * comp.mu)
        return out[rows]

    def component_counts(self) -> np.ndarray:
        return np.bincount(self.slots.live().track, minlength=len(self))

    # ------------------------------------------------------------------ late plots
    def track_priors(self, pred: IMMPrediction) -> tuple[list, list]:
        """The track-level prior per mode j: the moment match of the predicted components'
        mode j with weights ξ^c c_j."""
        comp, n = pred.comp, len(pred.rows)
        out = [
            moment_match(comp.w * comp.mu[:, j], comp.x[j], comp.P[j], pred.loc, n)[1:]
            for j in range(self.r)
        ]
        return [a for a, _ in out], [b for _, b in out]

    def retrodict(self, rows: np.ndarray, lag: np.ndarray, priors) -> IMMRetrodiction:
        """Every mode of the components of ``rows`` retrodicted with its own model (the
        coordinated turn with its backward flow and Jacobian) and the track's last prior
        of that mode (O1-O4). **Approximation**: no mode interaction over the lag (Π(−Δ)
        is not defined; Π(Δ) over Δ ≤ max_lateness is close to I for the configured
        chains); exact for one CV mode."""
        cur, loc = self.slots.rows(rows, len(self))
        known, xp, Pp = priors
        xs, Ps, Cs = [], [], []
        for j, model in enumerate(self.models):
            x, P, C = retrodict(
                model, cur.x[j], cur.P[j], lag[loc], xp[j][loc], Pp[j][loc], known[loc]
            )
            xs.append(x)
            Ps.append(P)
            Cs.append(C)
        retro = IMMComponents(cur.track, cur.w, cur.hist, cur.mu, xs, Ps)
        y = np.stack([xs[j][:, self.pos[j]] for j in range(self.r)], axis=1)
        HPH = np.stack([Ps[j][:, self.pos[j]][:, :, self.pos[j]] for j in range(self.r)], axis=1)
        return IMMRetrodiction(rows, retro, loc, y, HPH, current=cur, cross=Cs)

    def update_late(
        self, pred: IMMRetrodiction, table: IMMTable, beta0: np.ndarray, beta: np.ndarray
    ) -> None:
        """The "no plot" child keeps the current components with weight β₀ ξ^c and their
        μ; the child of plot i has every mode OOSM-updated ((O5) of
        :mod:`fusion.tracker.oosm`), weight β_i ξ^c p^c_i / p^τ_i and μ^c_j ∝ μ^c_j
        N_j(z(τ)) (eq. 19 with μ in place of c); then the merge and pruning."""
        cur, t = pred.current, table
        children = IMMComponents(
            cur.track, cur.w * beta0[pred.loc], _no_plot(cur.hist), cur.mu, cur.x, cur.P
        )
        if len(t.pair_comp):
            c, p = t.pair_comp, t.pair_plot
            w = cur.w[c] * beta[t.pair_row] * t.p_pair / t.p[t.pair_row]
            lw = t.log_n + np.log(np.maximum(cur.mu[c], 1e-300))
            mu = np.exp(lw - lw.max(axis=1, keepdims=True))
            mu /= mu.sum(axis=1, keepdims=True)
            xs, Ps = [], []
            for j in range(self.r):
                x, P = oosm_update(
                    cur.x[j][c], cur.P[j][c], pred.cross[j][c], self.H[j], t.nu[:, j], t.S[:, j]
                )
                xs.append(x)
                Ps.append(P)
            hist = shift_history(cur.hist[c], t.uid[p])
            upd = IMMComponents(cur.track[c], w, hist, mu, xs, Ps)
            children = IMMComponents.concat([children, upd])
        self.store_children(pred.rows, children, len(t.tp_track))

    # ------------------------------------------------------------------ snapshots
    def to_snapshot(self) -> dict:
        """The IMM components (the estimates and the gate's fixes are track-store columns)
        and the next plot history id."""
        return {"components": self.slots.to_snapshot(), "next_uid": self._next_uid}

    def from_snapshot(self, snap) -> None:
        snap = mapping(snap, "density")
        empty = self.slots.data.take(np.zeros(0, np.int64))
        slots = ComponentSlots.from_snapshot(snap.get("components"), empty, len(self))
        self.slots, self._next_uid = slots, entry(snap, "next_uid", int)

    @staticmethod
    def warm_up() -> None:
        """Load the compiled kernels of this density on tiny inputs: the pair likelihoods
        (k = 2 closed form, k = 3 Cholesky), the mode transition, the mixing's moment
        matching, the coordinated turn's prediction and layout conversions, the Kalman
        update of the gated pairs (k = 2 and another k), the Singer groups and pruning."""
        one = np.zeros(1, np.int64)
        for k in (2, 3):
            Sk = np.eye(k)[None]
            mode_pair_likelihoods(one, one, np.zeros((1, 1, k)), Sk[None].copy(),
                                  np.zeros((1, k)), Sk.copy(), np.ones((1, 1)))  # fmt: skip
        P = np.stack([np.eye(2), 2.0 * np.eye(2)])
        x = np.arange(4.0).reshape(2, 2)
        moment_match_rows_each(np.full((1, 2, 2), 0.5), x[None], P[None])
        ModeTransition(np.array([[0.9, 0.1], [0.2, 0.8]]), 4.0)(np.array([1.0, 2.0]))
        ct = CoordinatedTurn()
        xt, Pt = np.array([[0.0, 0.0, 0.5, 0.01, 200.0]]), np.eye(5)[None]
        ct.transition(xt, 4.0)
        ct.predict(xt, Pt, 4.0)
        ct.Q(4.0, xt)
        to_cv_layout(ct, xt, Pt)
        from_common(ct, *to_common(ct, xt, Pt))
        H2 = np.eye(2)
        update_with_innovation(np.zeros((2, 2)), P, H2, P + P, np.ones((2, 2)), P)  # k = 2
        update_with_innovation(np.zeros((2, 2)), P, H2[:1], P[:, :1, :1] + 1.0,
                               np.ones((2, 1)), P[:, :1, :1])  # k = 1 (any k != 2)  # fmt: skip
        history_groups(np.array([0, 0]), np.zeros((2, 1), np.int64))  # the Singer merge
        prune_indices(np.array([0, 0]), np.array([0.4, 0.6]), 1e-3, 30, 1)


def _no_plot(hist: np.ndarray) -> np.ndarray:
    """The plot history of a "no plot" child: id 0 first (:func:`~..its.shift_history`)."""
    return shift_history(hist, np.zeros(len(hist), np.int64))


def imm_density(cfg, second: str) -> IMMMixtureDensity:
    """The IMM density of a TrackerConfig: CV (q = ``imm_q_cv``) plus ``second`` =
    ``ct`` (coordinated turn, σ_a = ``imm_ct_sigma_a``, σ_ω = ``imm_ct_sigma_omega``) or
    ``singer`` (τ = ``imm_singer_tau``, σ_m = ``imm_singer_sigma_m``), 2-D or 3-D."""
    ndim = cfg.ndim
    qv = cfg.q_vertical if cfg.q_vertical is not None else cfg.imm_q_cv
    cv = ConstantVelocity(q=cfg.imm_q_cv, ndim=ndim, q_vertical=qv if ndim == 3 else None)
    if second == "ct":
        other = CoordinatedTurn(
            cfg.imm_ct_sigma_a, cfg.imm_ct_sigma_omega, vertical=ndim == 3, q_vertical=qv
        )
    elif second == "singer":
        other = Singer(tau=cfg.imm_singer_tau, sigma_m=cfg.imm_singer_sigma_m, ndim=ndim)
    else:
        raise ValueError(f"IMM second model {second!r}: must be 'ct' or 'singer'")
    return configured_density(cfg, [cv, other], cfg.imm_tpm, cfg.imm_mu0)


def configured_density(cfg, models: list, tpm, mu0) -> IMMMixtureDensity:
    """An IMM density of the ``models`` with the transition matrix ``tpm`` (r², row-major)
    per ``imm_tpm_period``, mode probabilities ``mu0`` of new tracks and every other
    setting (memory, pruning, initial acceleration, coasting, reachability, gating) from
    the TrackerConfig ``cfg``."""
    r = len(models)
    return IMMMixtureDensity(
        models,
        ModeTransition(np.reshape(tpm, (r, r)), cfg.imm_tpm_period),
        mu0,
        cfg.ndim,
        cfg.memory_depth,
        cfg.prune_threshold,
        cfg.max_components,
        cfg.imm_init_acceleration,
        cfg.imm_coast_after,
        cfg.imm_coast_step,
        cfg.v_max if cfg.reach_gate else None,
        cfg.imm_gating,
    )
