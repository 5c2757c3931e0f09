"""The Monte Carlo loop of one tracker variant: simulate → track → label → histories.

:class:`VariantRunner` keeps the tracker and the truth labeller of one
:class:`~fusion.evaluation.experiment.Variant` across runs, because the source carries
false tracks from one run into the next ([thesis] §7.1). Per run r:

1. ``build_scenario(scenario, seed=run_seed(seed, r))`` and the simulator's fast path give
   the scans (plots z, origin ``target_id``, −1 for clutter) and the true states at the
   scan times; the time axis is shifted by r·duration (run r + 1 follows run r);
2. every scan is one :class:`~fusion.tracker.MeasurementBatch` (R = σ² I, the sensor's
   P_D, the true clutter density at each plot for a known-clutter tracker) stepped
   through the tracker; CPU time (``time.process_time``) is summed over the tracker
   steps only;
3. each track is labelled with :class:`~fusion.metrics.labelling.TruthLabeller` (7.1)
   using the origin target of the plot the track selected this scan
   (``TrackerOutput.assigned_plot``: the most likely plot, when more likely than a miss);
4. rows of every track (run, scan, id, confirmed, label, position, ψ) and target go to
   columnar histories; duplicate deletions of confirmed tracks ("merged" events) are
   listed for the retention table;
5. at the end of the run the tracks labelled true are deleted and the initiation buffer is
   emptied; false tracks (confirmed or not) carry over (``carry_false_tracks``), else
   every track is deleted.

The loop is pure computation: the caller decides about processes, caching and progress.
A runner pickles (its state is NumPy arrays), so a block of runs can continue in another
process from where the previous block ended.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from skyfuse.fusion.metrics.history import TrackHistory, TruthHistory
from skyfuse.fusion.metrics.labelling import FALSE, TruthLabeller, two_point_covariance
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.fusion.sim.cartesian import clutter_density_at
from skyfuse.fusion.tracker import MeasurementBatch, Tracker
from skyfuse.fusion.tracker.initiation import PlotBuffer

from .experiment import Experiment, Variant, run_seed


@dataclass
class RunBlock:
    """Histories of consecutive runs of one variant.

    ``tracks``/``truth``: ``TrackHistory``/``TruthHistory`` rows (positions x, y in m);
    ``merged_run``, ``merged_track_id``, ``merged_scan`` (q,): confirmed tracks deleted as
    duplicates; ``cpu_s``: tracker CPU seconds; ``runs`` (b,) run indices and ``carried``
    (b,) false tracks carried into each run."""

    tracks: TrackHistory
    truth: TruthHistory
    merged_run: np.ndarray
    merged_track_id: np.ndarray
    merged_scan: np.ndarray
    cpu_s: float
    runs: np.ndarray
    carried: np.ndarray

    @classmethod
    def concat(cls, parts: list[RunBlock]) -> RunBlock:
        def cat(name: str, dtype) -> np.ndarray:
            if not parts:
                return np.zeros(0, dtype)
            return np.concatenate([getattr(p, name) for p in parts]).astype(dtype)

        return cls(
            tracks=TrackHistory.concat([p.tracks for p in parts]),
            truth=TruthHistory.concat([p.truth for p in parts]),
            merged_run=cat("merged_run", np.int64),
            merged_track_id=cat("merged_track_id", np.int64),
            merged_scan=cat("merged_scan", np.int64),
            cpu_s=float(sum(p.cpu_s for p in parts)),
            runs=cat("runs", np.int64),
            carried=cat("carried", np.int64),
        )

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Flat arrays (e.g. for ``np.savez``); inverse of :meth:`from_arrays`."""
        t, g = self.tracks, self.truth
        return {
            "t_run": t.run, "t_scan": t.scan, "t_id": t.track_id, "t_conf": t.confirmed,
            "t_label": t.label, "t_pos": t.position, "t_psi": t.existence,
            "g_run": g.run, "g_scan": g.scan, "g_id": g.target_id, "g_pos": g.position,
            "m_run": self.merged_run, "m_id": self.merged_track_id, "m_scan": self.merged_scan,
            "cpu_s": np.array(self.cpu_s), "runs": self.runs, "carried": self.carried,
        }  # fmt: skip

    @classmethod
    def from_arrays(cls, a: dict[str, np.ndarray]) -> RunBlock:
        return cls(
            tracks=TrackHistory(
                a["t_run"], a["t_scan"], a["t_id"], a["t_conf"].astype(bool), a["t_label"],
                a["t_pos"], a["t_psi"],
            ),
            truth=TruthHistory(a["g_run"], a["g_scan"], a["g_id"], a["g_pos"]),
            merged_run=a["m_run"], merged_track_id=a["m_id"], merged_scan=a["m_scan"],
            cpu_s=float(a["cpu_s"]), runs=a["runs"], carried=a["carried"],
        )  # fmt: skip


@dataclass
class RunInput:
    """The simulated data of one run, shared by all variants: per scan the scan number,
    time (ns, unshifted), plots z (m, 2) and their origin target ids; the true states
    (K, n, 4) interleaved [x, vx, y, vy] with alive (K, n) and target ids (n,); σ² and
    P_D of the sensor; the scenario duration (s) and scan period T (s); ``clutter_density``
    per scan the true clutter density at each plot (m⁻² per scan, the scenario's clutter
    regions, :func:`fusion.sim.cartesian.clutter_density_at`), what a tracker with
    ``clutter = "known"`` is told (the default non-parametric estimate ignores it); None
    = 0 at every plot."""

    scan: np.ndarray
    time_ns: np.ndarray
    z: list[np.ndarray]
    origin: list[np.ndarray]
    truth_state: np.ndarray
    truth_alive: np.ndarray
    target_id: np.ndarray
    sigma2: float
    p_detection: float
    duration: float
    period: float
    clutter_density: list[np.ndarray] | None = None


def simulate_run(exp: Experiment, run: int) -> RunInput:
    """Simulate run ``run`` of ``exp`` (same numbers for every variant)."""
    rs = run_seed(exp.seed, run)
    sc = build_scenario(exp.scenario, seed=rs, **exp.scenario_params)
    if len(sc.sites) != 1 or sc.sites[0].kind != "cartesian":
        raise ValueError(f"scenario {exp.scenario!r}: needs one planar cartesian sensor")
    site, sensor = sc.sites[0], sc.sensors[0]
    sim = Simulator(sc, seed=rs)
    scans = list(sim.scans())
    times = np.array([s.time_end for s in scans], dtype=np.int64)
    tr = sim.truth_at(times, geodetic=False)
    state = np.stack([tr["x"], tr["vx"], tr["y"], tr["vy"]], axis=-1)
    return RunInput(
        scan=np.array([s.scan for s in scans], dtype=np.int64),
        time_ns=times,
        z=[s.z for s in scans],
        origin=[s.target_id for s in scans],
        truth_state=state,
        truth_alive=tr["alive"],
        target_id=np.asarray(tr["target_id"], dtype=np.int64),
        sigma2=float(site.sigma_cartesian) ** 2,
        p_detection=float(site.p_detection),
        duration=float(sc.duration),
        period=float(site.scan_period),
        clutter_density=[clutter_density_at(sensor, s.z[:, 0], s.z[:, 1]) for s in scans],
    )


class VariantRunner:
    """Tracker + labeller of one variant, carried across runs (module docstring)."""

    def __init__(self, exp: Experiment, variant: Variant, psi_init: float | None = None) -> None:
        self.exp = exp
        self.variant = variant
        self.config = exp.tracker_config(variant, psi_init)
        self.tracker = Tracker(self.config)
        self.labeller: TruthLabeller | None = None
        self.next_run = 0

    def run(self, run: int, data: RunInput | None = None) -> RunBlock:
        """Run ``run`` (normally ``next_run``; runs must follow each other when false
        tracks are carried, which is checked)."""
        if self.exp.carry_false_tracks and run != self.next_run:
            raise ValueError(
                f"run {run}: this runner's next run is {self.next_run} (false tracks are "
                "carried from run to run, so runs of a variant are sequential)"
            )
        d = simulate_run(self.exp, run) if data is None else data
        if self.labeller is None:
            self.labeller = TruthLabeller(two_point_covariance(d.sigma2, d.period))
        trk, lab = self.tracker, self.labeller
        offset = round(run * d.duration * 1e9)
        R = d.sigma2 * np.eye(2)
        carried = len(trk.ids)
        keys = ("scan", "id", "conf", "label", "pos", "psi")
        rows: dict[str, list[np.ndarray]] = {k: [] for k in keys}
        g_rows: dict[str, list[np.ndarray]] = {k: [] for k in ("scan", "id", "pos")}
        merged: list[tuple[int, int]] = []
        cpu = 0.0
        label = np.zeros(0, np.int64)
        for j, k in enumerate(d.scan):
            batch = MeasurementBatch(
                time_ns=int(d.time_ns[j]) + offset,
                radar_id="sensor",
                z=d.z[j],
                R=R,
                p_detection=d.p_detection,
                clutter_density=0.0 if d.clutter_density is None else d.clutter_density[j],
                target_ids=d.origin[j],
            )
            t0 = time.process_time()
            out = trk.step(batch)
            cpu += time.process_time() - t0
            origin = np.asarray(out.batch.target_ids, dtype=np.int64)
            sel = np.full(len(out.ids), FALSE, dtype=np.int64)
            got = out.assigned_plot >= 0
            sel[got] = origin[out.assigned_plot[got]]
            alive = d.truth_alive[j]
            label = lab.step(
                out.ids,
                out.states,
                d.target_id[alive],
                d.truth_state[j][alive],
                sel.astype(np.int64),
            )
            n = len(out.ids)
            rows["scan"].append(np.full(n, k, np.int64))
            rows["id"].append(out.ids)
            rows["conf"].append(out.confirmed)
            rows["label"].append(label)
            rows["pos"].append(out.states[:, [0, 2]])
            rows["psi"].append(out.existence)
            g_rows["scan"].append(np.full(int(alive.sum()), k, np.int64))
            g_rows["id"].append(d.target_id[alive])
            g_rows["pos"].append(d.truth_state[j][alive][:, [0, 2]])
            merged.extend((e.track_id, int(k)) for e in out.events if e.kind == "merged")
        # end of run: true tracks deleted (false ones carried over), initiation restarts
        if self.exp.carry_false_tracks:
            trk.delete_tracks(out.ids[label != FALSE])
        else:
            trk.delete_tracks(trk.ids)
        trk.buffer = PlotBuffer.empty(trk.k)
        self.next_run = run + 1
        return _run_block(run, rows, g_rows, merged, cpu, carried)

    def run_many(self, runs: range | list[int]) -> RunBlock:
        """Runs in order, as one block."""
        return RunBlock.concat([self.run(r) for r in runs])


def _run_block(
    run: int, rows: dict, g_rows: dict, merged: list, cpu: float, carried: int
) -> RunBlock:
    """The histories of one run (per-scan arrays of :meth:`VariantRunner.run`) as a block."""
    nrow = sum(len(a) for a in rows["id"])
    ng = sum(len(a) for a in g_rows["id"])
    m = np.array(merged, dtype=np.int64).reshape(-1, 2)
    return RunBlock(
        tracks=TrackHistory(
            run=np.full(nrow, run, np.int64),
            scan=np.concatenate(rows["scan"]),
            track_id=np.concatenate(rows["id"]).astype(np.int64),
            confirmed=np.concatenate(rows["conf"]).astype(bool),
            label=np.concatenate(rows["label"]),
            position=np.concatenate(rows["pos"]).reshape(nrow, 2),
            existence=np.concatenate(rows["psi"]),
        ),
        truth=TruthHistory(
            run=np.full(ng, run, np.int64),
            scan=np.concatenate(g_rows["scan"]),
            target_id=np.concatenate(g_rows["id"]),
            position=np.concatenate(g_rows["pos"]).reshape(ng, 2),
        ),
        merged_run=np.full(len(m), run, np.int64),
        merged_track_id=m[:, 0],
        merged_scan=m[:, 1],
        cpu_s=cpu,
        runs=np.array([run], np.int64),
        carried=np.array([carried], np.int64),
    )
