"""Accuracy of the fusion service while it is overloaded, reproducibly: the live code
path (``FusionCore``: reorder buffer, overload policy, ``TrackPipeline``, the published
delta feed) on a simulated clock, fed with a recording sped up so that processing it
batch by batch would take L times as long as it lasts (the overload level L), each
tracker step costing a fixed time. Deterministic: the same numbers on any machine,
however loaded.

The recording: the ``regional`` scenario with truth (``--radars`` radars, ``--targets``
aircraft, ``--duration`` s, ``--seed``; the radars' own periods, 16 sectors). A tracker
step holding m plots costs a + b·m seconds of the clock (``--step-ms``, ``--plot-us``:
measured on the development machine, ``tracker`` steps of this scenario batch by batch
and coalesced); N batches and P plots take C = N·a + P·b batch by batch, so at speed
S = L·D / C (D the duration; data time = S × clock) the service is overloaded L times.
Each plot batch arrives when its sweep ends, the service holds it the reorder wait (clock
s), then applies the ready batches group by group with its overload policy (given the
true cost model: no learning, no wall-clock timing) and the clock advances by the cost
of the steps it took.

Scoring: each tracker step's delta (``delta_split_s`` → 0: a part per step) is applied
to a picture (``schemas.TrackPicture``, as a client does), stamped with its data time
(the newest sweep end applied); at every truth
time the scoring of ``skyfuse eval`` (``services.evaluation.observers.TruthObserver``:
the confirmed tracks of the latest picture, each predicted with constant velocity from
its own time, against the targets in coverage) gives the position RMSE (all, in turns,
straight), GOSPA and coverage. Scoring in data time leaves out the wall-clock latency
(reported apart, clock s) but keeps what widening costs: a coalesced step's plots are
in the picture only once its last sector is applied. L = 0 is the baseline: every step
free, batch by batch, the numbers of ``skyfuse eval`` on the same recording.

    python benchmarks/overload_accuracy.py [--levels 0,1.5,2,4] [--targets 300]
        [--radars 6] [--duration 300] [--seed 3] [--group-budget-s 0.1]
        [--coalesce-max-deg 360] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from skyfuse.fusion.sim import Simulator, build_scenario  # noqa: E402
from skyfuse.fusion.tracker.config import TrackerConfig  # noqa: E402
from skyfuse.schemas import TrackPicture  # noqa: E402
from skyfuse.services.cli.cmd_fusion import make_pipeline_factory  # noqa: E402
from skyfuse.services.evaluation import observers as obs  # noqa: E402
from skyfuse.services.fusion.overload import StepCost  # noqa: E402
from skyfuse.services.fusion.service import FusionConfig, FusionCore  # noqa: E402


def recording(a):
    """(sites, plot batches in time order, truth messages) of the scenario."""
    sc = build_scenario(
        "regional", seed=a.seed, duration=a.duration, targets=a.targets, radars=a.radars
    )
    sites, batches, truth = {}, [], []
    for ev in Simulator(sc, seed=a.seed).run():
        if ev.kind == "site":
            sites[ev.message.radar_id] = ev.message
        elif ev.kind == "plots":
            batches.append(ev.message)
        elif ev.kind == "truth":
            truth.append(ev.message)
    batches.sort(key=lambda b: b.time_end)
    return sites, batches, truth, sc.start_time


class Scorer:
    """The scoring of ``skyfuse eval`` (TruthObserver) fed in clock order: the plots
    (coverage) at their sweep ends, the client's picture as published, each truth
    message against the picture of that instant (built only then)."""

    def __init__(self, frame, batches, truth, t0_ns: int) -> None:
        self.ob = obs.TruthObserver(obs.Coverage())
        self.ob.start(frame)
        self.events = sorted(
            [((b.time_end - t0_ns) / 1e9, 0, b) for b in batches]
            + [((m.time - t0_ns) / 1e9, 1, m) for m in truth],
            key=lambda e: (e[0], e[1]),
        )
        self.next = 0
        self.picture = TrackPicture()
        self.dirty = False

    def until(self, t: float) -> None:
        """Every plot batch and truth message up to clock ``t`` (before a publication
        at t: a picture published at t is seen by truth after t)."""
        while self.next < len(self.events) and self.events[self.next][0] < t:
            _, kind, msg = self.events[self.next]
            self.next += 1
            if kind == 0:
                self.ob.on_plots(msg)
            else:
                if self.dirty:
                    self.ob.on_tracks(self.picture.batch())
                    self.dirty = False
                self.ob.on_truth(msg)

    def publish(self, t: float, delta) -> None:
        self.until(t)
        self.picture.apply(delta)
        self.dirty = True


class Run:
    """One level: the core, its simulated clock and what it published."""

    def __init__(self, a, sites, cost: tuple[float, float] | None) -> None:
        lat0 = float(np.mean([s.lat for s in sites.values()]))
        lon0 = float(np.mean([s.lon for s in sites.values()]))
        cfg = FusionConfig(
            reorder_wait=a.reorder_wait, frame_lat0=lat0, frame_lon0=lon0,
            delta_split_s=1e-9, future_tolerance="off", group_budget_s=a.group_budget_s,
            coalesce_max_deg=a.coalesce_max_deg, full_interval=1e9,
        )  # fmt: skip
        self.core = FusionCore(cfg, make_pipeline_factory(TrackerConfig(), cfg.fusion_id))
        self.cost = cost
        if cost is not None:
            self.core.overload.cost = StepCost(*cost, learn=False)
        for s in sites.values():
            self.core.on_site(s)
        self.latency: list[float] = []

        self.steps = self.plots = 0
        policy_step = self.core.overload.on_step

        def on_step(plots: int, seconds: float, width: float) -> None:  # count, then on
            self.steps += 1
            self.plots += plots
            policy_step(plots, seconds, width)

        self.core.overload.on_step = on_step

    def counts(self) -> tuple[int, int]:
        """(tracker steps, plots) applied so far."""
        return self.steps, self.plots

    def seconds(self, before: tuple[int, int]) -> float:
        """Clock time of what was applied since ``before`` (:meth:`counts`)."""
        steps, plots = (x - y for x, y in zip(self.counts(), before))
        return steps * self.cost[0] + plots * self.cost[1] if self.cost else 0.0


def drive(run: Run, batches, truth, t0_ns: int, speed: float) -> tuple[float, dict]:
    """Feed the batches at their sweep ends (clock = data time / ``speed``), apply them
    on the simulated clock, publish each delta to the scorer at its data time (the
    newest sweep end applied); returns the clock at the last publication and the truth
    scores."""
    data = [(b.time_end - t0_ns) / 1e9 for b in batches]
    arrive = [d / speed for d in data]
    i, t, stamp, core, scorer = 0, 0.0, 0.0, run.core, None
    while i < len(batches) or len(core.buffer):
        while i < len(batches) and arrive[i] <= t:
            core.on_plots(batches[i], arrival=arrive[i], recv_ns=batches[i].time_end)
            i += 1
        ready = core.buffer.pop_ready(t, limit=core.cfg.bulk_max)  # as ready_cycles
        if not ready:
            due = core.buffer.next_due()
            nxt = [x for x in (due, arrive[i] if i < len(batches) else None) if x is not None]
            if not nxt:
                break
            t = max(t, min(nxt) + 1e-9)  # (a hold ends at arrival + wait, up to rounding)
            continue
        before = run.counts()
        for out in core.cycle_group(ready, t):  # one part per tracker step
            t += run.seconds(before)
            before = run.counts()
            if scorer is None:
                scorer = Scorer(core.pipeline.frame, batches, truth, t0_ns)
            stamp = max(stamp, max((e - t0_ns) / 1e9 for e in out.time_ends))
            scorer.publish(stamp, out.tracks.model())
            run.latency += [t - (e - t0_ns) / 1e9 / speed for e in out.time_ends]
    scorer.until(float("inf"))
    return t, scorer.ob.summary().get("truth", {})


def level_result(level, run: Run, end: float, truth_scores: dict, wall: float) -> dict:
    st = run.core.status(now=end)
    c, lat = st.counters, np.array(run.latency)
    steps = run.counts()[0]
    return {
        "level": level,
        "cost_step_ms": None if run.cost is None else round(run.cost[0] * 1e3, 4),
        "cost_plot_us": None if run.cost is None else round(run.cost[1] * 1e6, 4),
        "batches": c["cycles"],
        "steps": steps,
        "batches_per_step": round(c["cycles"] / max(steps, 1), 3),
        "coalesced_steps": c["coalesced_steps"],
        "groups_widened": st.overload.groups_widened,
        "clock_end_s": round(end, 3),
        "latency_s": {p: round(float(np.percentile(lat, q)), 3)
                      for p, q in (("p50", 50), ("p90", 90), ("p99", 99), ("max", 100))},
        "position_rmse_m": truth_scores.get("position_rmse_m"),
        "position_rmse_by_phase": truth_scores.get("position_rmse_by_phase"),
        "coverage": truth_scores.get("coverage"),
        "gospa_mean_m": (truth_scores.get("gospa") or {}).get("mean_m"),
        "tracks_confirmed_end": st.tracks_confirmed,
        "wall_s": round(wall, 1),
    }  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--levels", default="0,1.5,2,4", help="overload levels L (0: free steps)")
    ap.add_argument("--targets", type=int, default=300)
    ap.add_argument("--radars", type=int, default=6)
    ap.add_argument("--duration", type=float, default=300.0)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--reorder-wait", type=float, default=0.2)
    ap.add_argument("--group-budget-s", type=float, default=0.1)
    ap.add_argument("--coalesce-max-deg", default="360", help="the fusion's bound ('off')")
    ap.add_argument("--step-ms", type=float, default=2.5, help="cost shape: fixed per step")
    ap.add_argument("--plot-us", type=float, default=19.0, help="cost shape: per plot")
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args()
    sites, batches, truth, t0 = recording(a)
    n, p = len(batches), sum(len(b) for b in batches)
    capacity_s = n * a.step_ms * 1e-3 + p * a.plot_us * 1e-6  # batch by batch, clock s
    print(f"regional seed {a.seed}, {a.radars} radars, {a.targets} aircraft, {a.duration:.0f} s: "
          f"{n} batches, {p} plots; load {os.getloadavg()}", flush=True)  # fmt: skip
    results = []
    for level in (float(x) for x in a.levels.split(",")):
        cost = (a.step_ms * 1e-3, a.plot_us * 1e-6) if level > 0 else None
        speed = (level or 1.0) * a.duration / capacity_s
        w0 = time.perf_counter()
        run = Run(a, sites, cost)
        end, scores = drive(run, batches, truth, t0, speed)
        r = level_result(level, run, end, scores, time.perf_counter() - w0)
        r["speed"] = round(speed, 3)
        print(json.dumps(r), flush=True)
        results.append(r)
    base = results[0]["position_rmse_m"] if results and results[0]["level"] == 0 else None
    for r in results:
        if base and r["position_rmse_m"]:
            r["rmse_over_batch_by_batch"] = round(r["position_rmse_m"] / base, 3)
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        cfg = {k: str(v) for k, v in vars(a).items()}
        a.json.write_text(json.dumps({"config": cfg, "levels": results}, indent=2))


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
