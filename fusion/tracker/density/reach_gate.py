"""Reachability gate of the IMM density from the last plot [IMPL] (docs/reports/tracker-log.md,
"Reachability gate"): a plot z_i can be the track's aircraft only if

    ‖z_i − p_f‖ ≤ v_max Δt + √g (σ_f + σ_i),                                        (C1)

p_f the track's position estimate after its last plot of weight > 0.5 (the fix), Δt the
time since (the sum of the predictions' dt), σ_f and σ_i the largest standard deviations
(√λ_max) of the fix's position and of the plot's R, g the gate. An aircraft moves at most
v_max; the fix and the plot are each off by at most √g σ with probability P_G per axis of
largest spread. Pairs outside are dropped before the likelihoods: they hold only after a
long, loose coast, where the mixture's prediction (its covariance from the linearised
turn mode) has outgrown the distance an aircraft can fly. The out-of-sequence update (a
plot older than the fix, :mod:`fusion.tracker.oosm`) is not gated.

State: three columns of the track store (:mod:`fusion.tracker.store`), declared only
when the gate is on (``speed`` not None): ``reach_p`` (n, ndim) the fix's position,
``reach_sigma`` (n,) its σ_f (m), ``reach_since`` (n,) Δt (s). Positions in the CV layout
[x, vx, y, vy(, z, vz)] of the system frame, metres.
"""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.filters.small_spd import largest_eigenvalue

from ..store import Column, ColumnGroup


def largest_sigma(C: np.ndarray) -> np.ndarray:
    """√λ_max (n,) of covariances C (n, k, k): the standard deviation along the widest axis."""
    return np.sqrt(np.maximum(largest_eigenvalue(C), 0.0))


class ReachGate:
    """The gate (C1) of one IMM density; ``speed`` v_max (m/s), None: no gate."""

    def __init__(self, speed: float | None, ndim: int) -> None:
        self.speed = speed
        self.ndim = ndim
        self.pos = [2 * a for a in range(ndim)]  # CV layout [x, vx, y, vy(, z, vz)]
        self.tracks = None

    @property
    def on(self) -> bool:
        return self.speed is not None

    def attach(self, tracks) -> None:
        """Declare the columns (gate on only); the fix of a new track is its initial state."""
        if not self.on:
            return
        tracks.declare(
            ColumnGroup(
                "reach gate",
                (Column("reach_p", np.float64, (self.ndim,), doc="position of the fix, m"),
                 Column("reach_sigma", np.float64, doc="largest σ of the fix's position, m"),
                 Column("reach_since", np.float64, fill=0.0, doc="time since the fix, s")),
                init=self._initial_fix,
            )
        )  # fmt: skip
        self.tracks = tracks

    def _initial_fix(self, new) -> dict:
        return {"reach_p": new.x[:, self.pos], "reach_sigma": self._sigma(new.P)}

    def _sigma(self, P: np.ndarray) -> np.ndarray:
        return largest_sigma(P[:, self.pos][:, :, self.pos])

    def predict(self, rows: np.ndarray, dt: np.ndarray) -> None:
        """The rows' clocks advance by their prediction intervals ``dt`` (s)."""
        if self.on:
            self.tracks.reach_since[rows] += np.maximum(dt, 0.0)

    def since(self, rows: np.ndarray) -> np.ndarray | None:
        """Δt (s,) of the rows (a copy); None when the gate is off."""
        return self.tracks.reach_since[rows].copy() if self.on else None

    def fix(self, rows: np.ndarray, x: np.ndarray, P: np.ndarray) -> None:
        """New fixes x (s, d), P (s, d, d) of the rows hit by a plot; their clocks restart."""
        if self.on and len(rows):
            t = self.tracks
            t.reach_p[rows], t.reach_sigma[rows] = x[:, self.pos], self._sigma(P)
            t.reach_since[rows] = 0.0

    def reachable(
        self, rows: np.ndarray, since: np.ndarray, z: np.ndarray, sigma_z: np.ndarray, g: float
    ) -> np.ndarray:
        """(P,) True where plot z (P, k), of largest σ ``sigma_z`` (P,), is reachable
        ``since`` (P,) s after the fix of ``rows`` (C1)."""
        if not self.on or len(rows) == 0:
            return np.ones(len(rows), bool)
        k = z.shape[1]
        t = self.tracks
        dist = np.linalg.norm(z - t.reach_p[rows][:, :k], axis=1)
        return dist <= self.speed * since + np.sqrt(g) * (t.reach_sigma[rows] + sigma_z)
