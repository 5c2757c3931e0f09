"""Analytic, vectorised target trajectories for the scenario simulator.

A trajectory is a chain of segments in a horizontal plane (x east, y north, metres:
the planar scenario plane or the stereographic system plane of [Dikić]) plus
height z above the WGS-84 ellipsoid (m). Each segment starts at time ``t0`` (s after
the scenario start) with position ``p0`` and velocity ``v0`` and moves with

* a constant turn rate ``omega`` (rad/s, positive = counter-clockwise = left turn):
  the horizontal velocity rotates, its magnitude is kept (a coordinated turn, the
  constant-turn model of [Dikić]), and/or
* a constant acceleration ``acc`` (m/s², used for the piecewise-constant acceleration
  truth of the thesis scenarios: per-interval white acceleration gives exactly the
  discrete process noise Q_T = q [[T⁴/4, T³/2], [T³/2, T²]] of [thesis] (3.39) / [LM-IPF] eq. 19).

The vertical channel is ``z = z0 + vz τ + az τ²/2``. Closed forms, τ = t − t0, a = ωτ:

    p(τ) = p0 + [[sin a/ω, −(1−cos a)/ω], [(1−cos a)/ω, sin a/ω]] v0 + acc τ²/2
    v(τ) = R(a) v0 + acc τ

evaluated with ``np.sinc`` so ω → 0 is exact (straight flight). Everything is evaluated
for arrays of (target, time) pairs at once; no per-target Python loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

G0 = 9.80665
"""Standard gravity, m/s² (for turn g-loads)."""


def propagate(
    p0: np.ndarray, v0: np.ndarray, omega: np.ndarray, acc: np.ndarray, tau: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity after ``tau`` seconds on one segment (closed form above).

    Shapes: ``p0``, ``v0``, ``acc`` (..., 3); ``omega``, ``tau`` (...). Units m, m/s,
    rad/s, m/s², s. Returns ``(p, v)`` of shape (..., 3)."""
    p0 = np.asarray(p0, float)
    v0 = np.asarray(v0, float)
    acc = np.asarray(acc, float)
    omega = np.asarray(omega, float)
    tau = np.asarray(tau, float)
    a = omega * tau
    s_over = tau * np.sinc(a / np.pi)  # sin(a)/ω
    c_over = tau * (0.5 * a) * np.sinc(a / (2.0 * np.pi)) ** 2  # (1 − cos a)/ω
    c, s = np.cos(a), np.sin(a)
    vx, vy, vz = v0[..., 0], v0[..., 1], v0[..., 2]
    half_t2 = 0.5 * tau * tau
    p = np.stack(
        [
            p0[..., 0] + s_over * vx - c_over * vy + acc[..., 0] * half_t2,
            p0[..., 1] + c_over * vx + s_over * vy + acc[..., 1] * half_t2,
            p0[..., 2] + vz * tau + acc[..., 2] * half_t2,
        ],
        axis=-1,
    )
    v = np.stack(
        [
            c * vx - s * vy + acc[..., 0] * tau,
            s * vx + c * vy + acc[..., 1] * tau,
            vz + acc[..., 2] * tau,
        ],
        axis=-1,
    )
    return p, v


@dataclass
class _Segment:
    t0: float
    p0: np.ndarray
    v0: np.ndarray
    omega: float
    acc: np.ndarray


class TrajectoryBuilder:
    """Build one target's trajectory as a chain of segments (times in s after the
    scenario start, plane metres, m/s).

    >>> b = TrajectoryBuilder(0.0, (0, 0, 3000), (200, 0, 0))
    >>> b.straight(30).turn_by(math.pi / 2, g_load=1.0).straight(60)  # doctest: +ELLIPSIS
    <...>
    """

    def __init__(self, t0: float, position, velocity) -> None:
        self.t = float(t0)
        self.p = np.asarray(position, float).reshape(3).copy()
        self.v = np.asarray(velocity, float).reshape(3).copy()
        if not (np.isfinite(self.p).all() and np.isfinite(self.v).all()):
            raise ValueError(f"position {self.p} / velocity {self.v} must be finite")
        self.segments: list[_Segment] = []

    @property
    def speed(self) -> float:
        """Horizontal speed, m/s."""
        return float(math.hypot(self.v[0], self.v[1]))

    def _add(self, duration: float, omega: float, acc) -> TrajectoryBuilder:
        duration = float(duration)
        if not duration >= 0.0:
            raise ValueError(f"segment duration = {duration}: must be >= 0 s")
        acc = np.zeros(3) if acc is None else np.asarray(acc, float).reshape(3)
        if duration == 0.0:
            return self
        self.segments.append(_Segment(self.t, self.p.copy(), self.v.copy(), float(omega), acc))
        self.p, self.v = propagate(self.p, self.v, omega, acc, duration)
        self.t += duration
        return self

    def straight(self, duration: float) -> TrajectoryBuilder:
        """Constant velocity (including the current vertical rate) for ``duration`` s."""
        return self._add(duration, 0.0, None)

    def accelerate(self, duration: float, acc) -> TrajectoryBuilder:
        """Constant acceleration ``acc`` (ax, ay, az) m/s² for ``duration`` s."""
        return self._add(duration, 0.0, acc)

    def turn(self, duration: float, omega: float) -> TrajectoryBuilder:
        """Coordinated turn at ``omega`` rad/s (positive = left) for ``duration`` s."""
        return self._add(duration, omega, None)

    def turn_by(self, angle: float, g_load: float) -> TrajectoryBuilder:
        """Turn the heading by ``angle`` rad (positive = left/counter-clockwise) with a
        lateral (centripetal) acceleration of ``g_load`` × 9.80665 m/s²."""
        if not g_load > 0.0:
            raise ValueError(f"g_load = {g_load}: must be > 0")
        v = self.speed
        if v <= 0.0:
            raise ValueError("cannot turn a target with zero horizontal speed")
        omega = math.copysign(g_load * G0 / v, angle)
        return self._add(abs(angle) / abs(omega), omega, None)

    def set_climb_rate(self, climb_rate: float) -> TrajectoryBuilder:
        """Change the vertical rate (m/s, positive up) from now on."""
        self.v[2] = float(climb_rate)
        return self

    def fly_to(
        self, x: float, y: float, altitude: float, *, g_load: float, max_climb_rate: float
    ) -> bool:
        """Turn towards the waypoint (x, y) at ``g_load`` (lateral) and fly straight to it,
        changing height linearly to ``altitude`` (m) at no more than ``max_climb_rate``.

        The turn ends on the tangent from the turn circle to the waypoint, so the
        straight leg passes exactly through it. Returns False (and adds nothing) if the
        waypoint lies inside the turn circle (unreachable with that g-load)."""
        v = self.speed
        if v <= 0.0:
            raise ValueError("cannot fly to a waypoint with zero horizontal speed")
        r = v * v / (g_load * G0)
        pos = self.p[:2]
        to_w = np.array([x, y]) - pos
        u = self.v[:2] / v
        cross = u[0] * to_w[1] - u[1] * to_w[0]
        left = np.array([-u[1], u[0]])
        angle = 0.0
        if abs(cross) > 1e-9 * max(1.0, float(np.hypot(*to_w))):
            s = 1.0 if cross > 0 else -1.0
            centre = pos + s * r * left
            cw = np.array([x, y]) - centre
            d = float(np.hypot(*cw))
            if d <= r * (1.0 + 1e-9):
                return False
            phi = math.atan2(cw[1], cw[0])
            u0 = math.atan2(pos[1] - centre[1], pos[0] - centre[0])
            beta = math.acos(r / d)
            if s > 0:  # counter-clockwise: tangent point at φ − β
                angle = (phi - beta - u0) % (2 * math.pi)
            else:  # clockwise: tangent point at φ + β
                angle = -((u0 - (phi + beta)) % (2 * math.pi))
            turn_time = abs(angle) * r / v
            straight_len = math.sqrt(max(d * d - r * r, 0.0))
        else:
            if float(np.dot(u, to_w)) <= 0.0:
                return False  # waypoint straight behind
            turn_time = 0.0
            straight_len = float(np.hypot(*to_w))
        leg_time = turn_time + straight_len / v
        if leg_time <= 0.0:
            return True
        climb = (float(altitude) - self.p[2]) / leg_time
        climb = float(np.clip(climb, -max_climb_rate, max_climb_rate))
        self.set_climb_rate(climb)
        if turn_time > 0.0:
            self._add(turn_time, math.copysign(v / r, angle), None)
        self._add(straight_len / v, 0.0, None)
        return True


@dataclass
class TargetSet:
    """All targets of a scenario as padded segment arrays (n targets × S segments).

    Times are seconds after the scenario start. ``t_birth`` ≤ t < ``t_death`` is when a
    target exists (enters/leaves the scene). Before its first segment a trajectory is
    extrapolated backwards on that segment, after its last one it continues on it; the
    builders always end with a straight segment."""

    target_id: np.ndarray  # (n,) int64
    t_birth: np.ndarray  # (n,) s
    t_death: np.ndarray  # (n,) s
    seg_t0: np.ndarray  # (n, S) s, padded with +inf
    seg_p0: np.ndarray  # (n, S, 3) m
    seg_v0: np.ndarray  # (n, S, 3) m/s
    seg_omega: np.ndarray  # (n, S) rad/s
    seg_acc: np.ndarray  # (n, S, 3) m/s²
    mode_s: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # -1 = none
    mode_3a: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # -1 = none
    # identity (fusion.sim.identity): callsign ("" = none), the code from
    # mode_3a_change_time on (s; inf = never), enhanced surveillance (downlinks BDS 5,0/6,0)
    callsign: np.ndarray = field(default_factory=lambda: np.zeros(0, object))
    mode_3a_after: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    mode_3a_change_time: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ehs: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))

    def __post_init__(self) -> None:
        n = len(self.target_id)
        if self.mode_s.size == 0:
            self.mode_s = np.full(n, -1, np.int64)
        if self.mode_3a.size == 0:
            self.mode_3a = np.full(n, -1, np.int64)
        if self.callsign.size == 0:
            self.callsign = np.full(n, "", object)
        if self.mode_3a_after.size == 0:
            self.mode_3a_after = np.full(n, -1, np.int64)
        if self.mode_3a_change_time.size == 0:
            self.mode_3a_change_time = np.full(n, np.inf)
        if self.ehs.size == 0:
            self.ehs = np.zeros(n, bool)
        if len(np.unique(self.target_id)) != n:
            raise ValueError("target ids must be unique")

    def __len__(self) -> int:
        return len(self.target_id)

    @classmethod
    def from_builders(
        cls,
        builders: list[TrajectoryBuilder],
        *,
        target_id=None,
        t_birth=None,
        t_death=None,
        mode_s=None,
        mode_3a=None,
    ) -> TargetSet:
        """Pack builders into arrays. Each builder gets a final open straight segment."""
        n = len(builders)
        if n == 0:
            raise ValueError("a scenario needs at least one target")
        segs = []
        for b in builders:
            s = list(b.segments)
            s.append(_Segment(b.t, b.p.copy(), b.v.copy(), 0.0, np.zeros(3)))
            segs.append(s)
        width = max(len(s) for s in segs)
        t0 = np.full((n, width), np.inf)
        p0 = np.zeros((n, width, 3))
        v0 = np.zeros((n, width, 3))
        om = np.zeros((n, width))
        acc = np.zeros((n, width, 3))
        for i, s in enumerate(segs):
            for j, g in enumerate(s):
                t0[i, j] = g.t0
                p0[i, j] = g.p0
                v0[i, j] = g.v0
                om[i, j] = g.omega
                acc[i, j] = g.acc
        ids = np.arange(n, dtype=np.int64) if target_id is None else np.asarray(target_id)
        birth = t0[:, 0].copy() if t_birth is None else np.asarray(t_birth, float)
        death = np.full(n, np.inf) if t_death is None else np.asarray(t_death, float)
        return cls(
            target_id=ids.astype(np.int64),
            t_birth=birth,
            t_death=death,
            seg_t0=t0,
            seg_p0=p0,
            seg_v0=v0,
            seg_omega=om,
            seg_acc=acc,
            mode_s=np.zeros(0, np.int64) if mode_s is None else np.asarray(mode_s, np.int64),
            mode_3a=np.zeros(0, np.int64) if mode_3a is None else np.asarray(mode_3a, np.int64),
        )

    def state(self, t, index=None) -> tuple[np.ndarray, np.ndarray]:
        """Position (m, plane x/y and height z) and velocity (m/s) of targets ``index`` at
        times ``t`` (s after the start); ``t`` and ``index`` broadcast together
        (``index=None`` means all targets, then ``t`` must broadcast to (n,)).
        Returns arrays of shape broadcast(t, index) + (3,)."""
        if index is None:
            index = np.arange(len(self))
        t, index = np.broadcast_arrays(np.asarray(t, float), np.asarray(index, np.int64))
        shape = t.shape
        t = t.ravel()
        index = index.ravel()
        starts = self.seg_t0[index]
        k = np.maximum((starts <= t[:, None]).sum(axis=1) - 1, 0)
        tau = t - self.seg_t0[index, k]
        p, v = propagate(
            self.seg_p0[index, k],
            self.seg_v0[index, k],
            self.seg_omega[index, k],
            self.seg_acc[index, k],
            tau,
        )
        return p.reshape((*shape, 3)), v.reshape((*shape, 3))

    def alive(self, t, index=None) -> np.ndarray:
        """True where t_birth ≤ t < t_death (broadcast like :meth:`state`)."""
        if index is None:
            index = np.arange(len(self))
        t, index = np.broadcast_arrays(np.asarray(t, float), np.asarray(index, np.int64))
        return (self.t_birth[index] <= t) & (t < self.t_death[index])
