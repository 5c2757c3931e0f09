"""Calibration of ψ_init so that an experiment yields a target number of confirmed false
tracks ([thesis] §7.1: 15 ± 10 % per multi-target experiment, 20 ± 10 % single
target, so that CTT curves compare at equal false-track counts; [thesis] §7.1-7.2).

The count of confirmed false tracks over a fixed set of runs (fixed seeds) is a
non-decreasing step function of ψ_init in practice (a higher initial existence confirms
more tracks, true and false alike). :func:`calibrate_psi_init` searches log ψ_init:

1. **bracket**: from ``psi0`` multiply or divide by ``factor`` until the count crosses the
   target (or the bounds ``lo``/``hi`` are reached);
2. **refine**: regula falsi on (log ψ, log(count + ½)) — the count grows roughly as a
   power of ψ_init — with the new point kept at least 15 % of the bracket (in log ψ) from
   either end;

stopping when |count − target| ≤ tolerance or after ``max_evals`` evaluations (then, if no
evaluation on either side has another count, one probe at 2ψ or ψ/2 for the slope). The
result is the evaluated ψ with the count nearest the target (:func:`best_evaluation`:
among equal counts below the target the largest ψ, above it the smallest). When no
evaluation reaches the target, ``hi`` is evaluated (one evaluation beyond ``max_evals``
if needed) and ψ_init = ``hi`` (all counts above: ``lo``), whatever the noise of the
small counts says.

**Sampling error** (:func:`sampling_interval`). Over a given set of runs the count is one
draw of a roughly Poisson number with mean μ(ψ); another set of runs would move the
calibrated ψ. With the elasticity b = d log μ / d log ψ (a least-squares fit over the
evaluations) the delta method gives SE(log ψ*) = SE(log count)/b =
1/(b √count), and a 95 % interval ψ* · exp(± 1.96 SE). At the source's 15 false tracks
SE(log count) = 0.26; with b ≈ 1 that is a factor ×/÷ 1.66 on ψ_init.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass
class Calibration:
    """Result: ``psi_init``, its ``count``, the ``target`` and ``tolerance``, whether the
    count is within tolerance (``converged``) and every (ψ, count) evaluated."""

    psi_init: float
    count: float
    target: float
    tolerance: float
    converged: bool
    evaluations: list[tuple[float, float]] = field(default_factory=list)

    def as_dict(self) -> dict:
        err = sampling_interval(self.evaluations, self.psi_init, self.count)
        return {
            "psi_init": self.psi_init,
            "false_tracks": self.count,
            "target": self.target,
            "tolerance": self.tolerance,
            "converged": self.converged,
            "evaluations": [[round(p, 8), c] for p, c in self.evaluations],
            **err,
        }


def sampling_interval(evals: list[tuple[float, float]], psi: float, count: float) -> dict:
    """Sampling error of the calibrated ψ (module docstring): ``elasticity`` b,
    ``psi_se_log`` = 1/(b √max(count, 1)) and ``psi_interval_95`` [ψ e^{−1.96 SE},
    ψ e^{1.96 SE}]. b is the least-squares slope of log count on log ψ over all
    evaluations (those with count > 0 if at least two distinct ψ have one, else of
    log(count + ½)): the count over a fixed set of runs is a jagged step function, so the
    slope between neighbouring evaluations is not that of the mean μ(ψ). All None when
    the slope is not positive or fewer than two distinct ψ were evaluated."""
    none = {"elasticity": None, "psi_se_log": None, "psi_interval_95": None}
    pos = [(p, c) for p, c in evals if c > 0]
    pts = pos if len({p for p, _ in pos}) >= 2 else [(p, c + 0.5) for p, c in evals]
    if len({p for p, _ in pts}) < 2:
        return none
    x = [math.log(p) for p, _ in pts]
    y = [math.log(c) for _, c in pts]
    mx, my = sum(x) / len(x), sum(y) / len(y)
    sxx = sum((a - mx) ** 2 for a in x)
    b = sum((a - mx) * (c - my) for a, c in zip(x, y)) / sxx
    if not b > 0:
        return none
    se = 1.0 / (b * math.sqrt(max(count, 1.0)))
    interval = [psi * math.exp(-1.96 * se), min(psi * math.exp(1.96 * se), 1.0)]
    return {"elasticity": b, "psi_se_log": se, "psi_interval_95": interval}


def best_evaluation(
    evals: list[tuple[float, float]], target: float, tolerance: float = 0.0
) -> tuple[float, float]:
    """The (ψ, count) nearest the target; among equal counts below the target the largest
    ψ (it confirms true tracks soonest at that false-track count), above it the smallest.

    When every count is below ``target − tolerance`` (the target is out of reach) the
    largest ψ evaluated, when every count is above ``target + tolerance`` the smallest:
    the count is non-decreasing in ψ, so that is where its mean is nearest the target.
    Small noisy counts (0-4 false tracks over 500 runs) otherwise make the nearest count
    fall at an arbitrary ψ, e.g. 4 at ψ = 3.5·10⁻⁴ against 0-1 up to ψ = 0.18."""
    if not evals:
        raise ValueError("evals: empty: nothing to choose from")
    side = _out_of_reach(evals, target, tolerance)
    if side == "below":
        return max(evals, key=lambda e: e[0])
    if side == "above":
        return min(evals, key=lambda e: e[0])
    return min(evals, key=lambda e: (abs(e[1] - target), -e[0] if e[1] < target else e[0]))


def _check_search(
    target: float, tolerance: float, psi0: float, lo: float, hi: float, max_evals: int
) -> None:
    if not 0 < lo < hi < 1:
        raise ValueError(f"lo = {lo}, hi = {hi}: need 0 < lo < hi < 1")
    if not lo <= psi0 <= hi:
        raise ValueError(f"psi0 = {psi0}: must be within [lo, hi] = [{lo}, {hi}]")
    if target < 0 or tolerance < 0:
        raise ValueError(f"target = {target}, tolerance = {tolerance}: must be >= 0")
    if max_evals < 1:
        raise ValueError(f"max_evals = {max_evals}: must be >= 1")


def _evaluate_bound(
    evals: list[tuple[float, float]],
    f: Callable[[float], float],
    target: float,
    tolerance: float,
    lo: float,
    hi: float,
) -> None:
    """Target out of reach on one side: evaluate the bound itself (one evaluation beyond
    ``max_evals`` if the bracket ran out of them), so that the result is ψ = hi (or lo)."""
    psis = [p for p, _ in evals]
    side = _out_of_reach(evals, target, tolerance)
    if side == "below" and max(psis) < hi:
        f(hi)
    elif side == "above" and min(psis) > lo:
        f(lo)


def _out_of_reach(evals: list[tuple[float, float]], target: float, tolerance: float) -> str | None:
    """ "below" when every count is below ``target − tolerance``, "above" when every count
    is above ``target + tolerance``, else None (the target is within the counts' range)."""
    if all(c < target - tolerance for _, c in evals):
        return "below"
    if all(c > target + tolerance for _, c in evals):
        return "above"
    return None


def calibrate_psi_init(
    count: Callable[[float], float],
    target: float,
    tolerance: float,
    *,
    psi0: float = 0.01,
    lo: float = 1e-6,
    hi: float = 0.5,
    factor: float = 4.0,
    max_evals: int = 10,
) -> Calibration:
    """Search ψ_init in [lo, hi] with count(ψ) ≈ target (module docstring)."""
    _check_search(target, tolerance, psi0, lo, hi, max_evals)
    evals: list[tuple[float, float]] = []

    def f(psi: float) -> float:
        c = float(count(psi))
        evals.append((psi, c))
        return c

    def done() -> Calibration:
        _evaluate_bound(evals, f, target, tolerance, lo, hi)
        best = best_evaluation(evals, target, tolerance)
        if len(evals) < max_evals and sampling_interval(evals, *best)["elasticity"] is None:
            # one probe a factor 2 away measures the slope for the sampling error
            f(best[0] * 2.0 if best[0] * 2.0 <= hi else best[0] / 2.0)
            best = best_evaluation(evals, target, tolerance)
        return Calibration(
            best[0], best[1], target, tolerance, abs(best[1] - target) <= tolerance, evals
        )

    def ok(c: float) -> bool:
        return abs(c - target) <= tolerance

    psi = psi0
    c = f(psi)
    if ok(c):
        return done()
    # 1. bracket: a (count below target) < b (count above)
    a = b = None
    ca = cb = 0.0
    if c < target:
        a, ca = psi, c
        while len(evals) < max_evals and psi < hi:
            psi = min(psi * factor, hi)
            c = f(psi)
            if ok(c):
                return done()
            if c > target:
                b, cb = psi, c
                break
            a, ca = psi, c
    else:
        b, cb = psi, c
        while len(evals) < max_evals and psi > lo:
            psi = max(psi / factor, lo)
            c = f(psi)
            if ok(c):
                return done()
            if c < target:
                a, ca = psi, c
                break
            b, cb = psi, c
    if a is None or b is None:
        return done()
    # 2. refine in log ψ
    la, lb = math.log(a), math.log(b)
    while len(evals) < max_evals and lb - la > 1e-3:
        ya, yb, yt = math.log(ca + 0.5), math.log(cb + 0.5), math.log(target + 0.5)
        t = (yt - ya) / (yb - ya) if yb > ya else 0.5
        t = min(max(t, 0.15), 0.85)  # safeguard: never closer than 15 % to an end
        lm = la + t * (lb - la)
        c = f(math.exp(lm))
        if ok(c):
            break
        if c < target:
            la, ca = lm, c
        else:
            lb, cb = lm, c
    return done()
