"""The fusion service's overload policy: how wide its tracker steps are.

While the service keeps up, every plot batch is one tracker step (the published tracks
are those of batch-by-batch processing). When it falls behind, several contiguous sector
batches of one radar are ready together, and applying them as one wider step
(:mod:`~skyfuse.services.fusion.coalesce`) costs about as much as one batch: the
tracker's work per step is mostly fixed. This module decides how many batches each step
may take, from the backlog and the measured cost of a step.

**Cost model.** A tracker step of m plots costs c(m) = a + b·m seconds (a: the fixed
part — prediction, gating and management of the swept tracks, Python overhead; b: per
plot). a and b are estimated online by recursive least squares with forgetting factor
λ over every step's measured (m, seconds) (:class:`StepCost`), and a group's measured
wall time over the sum of its steps' predictions (conversion, feed messages and their
publication are paid per group) gives the scale s (an exponential average).

**Widening.** A group of B ready batches (P plots; :meth:`FusionCore.ready_cycles`)
applied batch by batch is predicted to take T(1) = s·(B·a + b·P). If T(1) is within the
budget ``group_budget_s``, nothing changes. Otherwise the smallest k ≥ 2 is taken such
that splitting each radar's contiguous run (at most ``coalesce_max_deg`` wide) into steps
of at most k batches gives S(k) steps with T(k) = s·(S(k)·a + b·P) within the budget
(the widest steps if none does). In a steady overload the group holds what arrived while
the previous one ran, B ≈ λ_b·T, so the k that fits is k ≈ λ_b·a / (1 − λ_b·b·m̄)
(λ_b batches per second, m̄ plots per batch): independent of the budget, the least
widening that keeps up; a larger backlog (a bigger group) widens more and is worked off
in a few groups, after which the steps narrow again. The budget sets how long a group
runs, so the lag (and the latency beyond the reorder wait) stays near one budget; a group
whose oldest batch is already overdue by more than a budget (after a burst, or while the
cost model learns) gets less time, T²/lag (:meth:`OverloadPolicy.budget`).
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from skyfuse.schemas import PlotBatch
from skyfuse.schemas.status import OverloadStatus
from skyfuse.services.fusion import coalesce

FORGETTING = 0.995
"""RLS forgetting factor λ per step: the estimate follows a cost that drifts over a few
hundred steps (more tracks, another load on the machine)."""

PRIOR = (1e3, 1e-1)
"""Π₀ = diag(PRIOR): the inverse information of the prior (a, b), about a thousandth of one
step's (xxᵀ with x = (1, m), m ≈ 100 plots): the measurements take over at once. Π is
also capped at it (forgetting does not wind up the directions no step excites)."""

INITIAL_SCALE = 2.0
"""The scale s before any group was measured: a group's wall time was about twice its
steps' on the development machine at 20,000 plots/s (conversion, feed messages)."""

SCALE_GAIN = 0.2
"""Weight of the newest group in the exponential average of the scale s."""


class StepCost:
    """Online estimate of the cost of one tracker step, c(m) = a + b·m seconds (module
    docstring), by recursive least squares with forgetting:
    K = Π x / (λ + xᵀ Π x), θ ← θ + K (y − xᵀθ), Π ← (Π − K xᵀ Π) / λ, x = (1, m).
    ``learn=False`` keeps the prior (tests, a replay with a simulated clock)."""

    def __init__(
        self, a: float = 3e-3, b: float = 2e-5, *, learn: bool = True, scale: float = 1.0
    ) -> None:
        self.theta = np.array([a, b], dtype=np.float64)
        self.cov = np.diag(PRIOR).astype(np.float64)
        self.learn = learn
        self.scale = scale
        self.steps = 0

    @property
    def a(self) -> float:
        return max(float(self.theta[0]), 1e-6)

    @property
    def b(self) -> float:
        return max(float(self.theta[1]), 0.0)

    def predict(self, steps: int, plots: int) -> float:
        """Predicted seconds of ``steps`` steps holding ``plots`` plots, with the scale."""
        return self.scale * (steps * self.a + plots * self.b)

    def add_step(self, plots: int, seconds: float) -> None:
        """One measured step."""
        self.steps += 1
        if not self.learn or not math.isfinite(seconds):
            return
        x = np.array([1.0, float(plots)])
        pred = float(x @ self.theta)
        # a step paused by the garbage collector or the scheduler is not its cost
        y = min(seconds, 3.0 * max(pred, 1e-4))
        px = self.cov @ x
        gain = px / (FORGETTING + float(x @ px))
        self.theta = self.theta + gain * (y - pred)
        self.cov = (self.cov - np.outer(gain, px)) / FORGETTING
        self.cov = 0.5 * (self.cov + self.cov.T)
        np.fill_diagonal(self.cov, np.minimum(np.diag(self.cov), PRIOR))  # no wind-up

    def add_group(self, predicted_steps_s: float, seconds: float) -> None:
        """A group's measured wall time against the sum of its steps' predictions."""
        if not self.learn or predicted_steps_s <= 0 or not math.isfinite(seconds):
            return
        ratio = min(max(seconds / predicted_steps_s, 0.5), 4.0)
        self.scale += SCALE_GAIN * (ratio - self.scale)


@dataclass
class _Group:
    t: float
    batches: int
    steps: int
    widest: float
    widened: bool
    seconds: float


class OverloadPolicy:
    """Chooses the largest number of batches per tracker step for each group (module
    docstring) and keeps what :meth:`status` reports. ``max_width`` rad: the widest step
    (None: never widen); ``budget_s``: the time a group should take; ``window_s``: the
    window of the Status figures."""

    def __init__(
        self,
        max_width: float | None,
        budget_s: float,
        *,
        window_s: float = 5.0,
        cost: StepCost | None = None,
    ) -> None:
        self.max_width = max_width
        self.budget_s = budget_s
        self.window_s = window_s
        self.cost = cost or StepCost(scale=INITIAL_SCALE)
        self.groups: deque[_Group] = deque(maxlen=10_000)
        self.active_from: float | None = None
        self.groups_widened = 0
        self.widened_s = 0.0
        self._last_widened: float | None = None
        self._cur: list = [0, 0.0, 0.0, 0.0]

    @property
    def enabled(self) -> bool:
        return self.max_width is not None

    def members(
        self,
        batches: Sequence[PlotBatch],
        mergeable: Sequence[bool],
        sources=None,
        lag: float = 0.0,
    ) -> int:
        """The most batches per step for this group: 1 (batch by batch) unless applying
        them one by one is predicted to exceed the budget. ``lag``: how long the oldest of
        them is overdue (past its reorder hold), s; beyond one budget the group gets
        less time (:meth:`budget`), so a lag left by a burst is worked off quickly."""
        n = len(batches)
        if not self.enabled or n < 2:
            return 1
        plots = sum(len(b.time) for b in batches)
        budget = self.budget(lag)
        if self.cost.predict(n, plots) <= budget:
            return 1
        runs = coalesce.plan(batches, mergeable, self.max_width, sources)
        lengths = [len(r) for r in runs]
        longest = max(lengths)
        for k in range(2, longest + 1):
            steps = sum(-(-m // k) for m in lengths)
            if self.cost.predict(steps, plots) <= budget:
                return k
        return longest

    def budget(self, lag: float) -> float:
        """The time for a group whose oldest batch is ``lag`` s overdue: the configured
        budget T while lag ≤ T, else T²/lag (at least T/4): the service that keeps up has
        a lag below one budget, a burst leaves more, and the steps then widen more until
        the lag is back under T."""
        t = self.budget_s
        return t if lag <= t else max(t * t / lag, 0.25 * t)

    def start_group(self) -> None:
        """A group starts: its steps are reported to :meth:`on_step`."""
        self._cur = [0, 0.0, 0.0, time.perf_counter()]  # steps, widest, predicted, t0

    def on_step(self, plots: int, seconds: float, width: float) -> None:
        """One tracker step of the current group: ``plots``, its measured ``seconds``
        and its azimuth ``width`` (rad)."""
        cur = self._cur
        cur[0] += 1
        cur[1] = max(cur[1], width)
        cur[2] += self.cost.predict(1, plots) / self.cost.scale
        self.cost.add_step(plots, seconds)

    def end_group(self, now: float, batches: int) -> None:
        """The current group is done (its outputs published): ``batches`` were released
        for it; ``now``: the service clock of the Status windows."""
        steps, widest, predicted, t0 = self._cur
        seconds = time.perf_counter() - t0
        self.cost.add_group(predicted, seconds)
        widened = 0 < steps < batches
        self.groups.append(_Group(now, batches, steps, widest, widened, seconds))
        while now - self.groups[0].t > self.window_s:  # only the window is reported
            self.groups.popleft()
        if widened:
            self.groups_widened += 1
            self.widened_s += seconds
            last = self._last_widened
            if self.active_from is None or last is None or now - last > self.window_s:
                self.active_from = now
            self._last_widened = now

    def status(self, now: float) -> OverloadStatus:
        """The policy's Status part over the last ``window_s`` (its clock: ``now``)."""
        recent = [g for g in self.groups if now - g.t <= self.window_s]
        batches = sum(g.batches for g in recent)
        steps = sum(g.steps for g in recent)
        widened = [g for g in recent if g.widened]
        active = bool(widened)
        return OverloadStatus(
            enabled=self.enabled,
            active=active,
            active_for_s=max(0.0, now - self.active_from)
            if active and self.active_from is not None
            else 0.0,
            batches_per_step=batches / steps if steps else 1.0,
            widest_deg=math.degrees(max((g.widest for g in recent), default=0.0)),
            busy_share=min(1.0, sum(g.seconds for g in recent) / self.window_s),
            max_deg=None if self.max_width is None else math.degrees(self.max_width),
            budget_s=self.budget_s,
            step_cost_ms=self.cost.a * 1e3,
            plot_cost_us=self.cost.b * 1e6,
            cost_scale=self.cost.scale,
            groups_widened=self.groups_widened,
            widened_s=self.widened_s,
        )
