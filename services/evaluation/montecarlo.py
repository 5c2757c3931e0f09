"""Monte Carlo tracker evaluation on the planar thesis scenarios: worker processes, the
resumable cache, ψ_init calibration, progress and the output files of ``skyfuse eval``.

The computation is :mod:`fusion.evaluation`; this module schedules it:

* **Parallel across variants.** False tracks are carried from run to run ([thesis] §7.1), so
  the runs of one variant form a chain; different variants are independent. Each variant
  advances in blocks of ``block`` runs; a finished block submits the next block of the
  same variant, with the runner's pickled state (tracker + labeller). Every variant's
  numbers depend only on the experiment and its ψ_init, never on the number of workers
  or the block size (the run seeds and time offsets are functions of the run index).
* **Resumable.** With a cache directory, each block's histories (``.npz``) and the state
  after it (``.pkl``) are written under a directory named by the experiment's settings
  (not its run count) and the variant's ψ_init; an interrupted or extended experiment
  continues after the last complete block.
* **Engines** (:class:`Engine`): in this process (one worker), a local process pool, or
  Dask (``dask.distributed``, the ``cluster`` extra): a local cluster of ``workers``
  single-threaded worker processes on 127.0.0.1, or an existing cluster by its scheduler
  address (``tcp://HOST:8786``). Tasks carry everything they need (experiment JSON,
  variant key, ψ_init, run range, pickled runner state), so the engine changes only where
  a block runs, never its numbers.
* **Calibration** (``calibrate``): per variant, ψ_init is searched
  (:func:`fusion.evaluation.calibrate_psi_init`) so that the first ``calibration_runs``
  runs (default: all runs, as the source) give the source's confirmed false tracks
  scaled to that many runs
  (15 per 500 multi-target, 20 per 500 single-target, ± 10 %, at least ± 0.5), counting
  the tracks that were false when they reached confirmation (see
  :mod:`fusion.evaluation.summary`). Each evaluation goes through the run cache (same
  directories and blocks as the runs), so an interrupted calibration continues where it
  stopped and the runs at the calibrated ψ_init are read back, not run again; a
  calibration file already there (e.g. from fewer runs) gives the starting ψ_init per
  variant, searched with a narrower bracket (:data:`WARM_FACTOR`), and each variant is
  saved to it as it finishes.
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, Field
from skyfuse.fusion.evaluation import (
    Experiment,
    RunBlock,
    Variant,
    VariantRunner,
    calibrate_psi_init,
    summarise,
)
from skyfuse.fusion.evaluation.experiment import SOURCE_RUNS
from skyfuse.fusion.evaluation.summary import false_at_confirmation
from skyfuse.fusion.metrics.retention import ROW_KEYS, retention_markdown

Advance = Callable[[int], None]
#: Bumped when the tracker's numbers change for the same settings (2: m̂ of 2.35 counted
#: in the track-level gate), so that older cached blocks are not reused.
CACHE_VERSION = 2
#: Version of the known-clutter runs alone (2: the runner tells a ``clutter = "known"``
#: tracker the scenario's true density at each plot, it used to pass 0), so that the
#: still valid non-parametric caches keep being reused.
KNOWN_CLUTTER_VERSION = 2
EngineKind = Literal["auto", "dask", "processes"]


class TrackerEvalConfig(BaseModel):
    """Options of ``skyfuse eval SCENARIO --trackers ...`` (thesis and lm-ipf scenarios)."""

    scenario: str = Field(description="Planar scenario (thesis-*, lm-ipf-*)")
    runs: int = Field(100, ge=1, le=100_000, description="Monte Carlo runs")
    seed: int = Field(1, ge=0, description="Seed; run r uses seed·100003 + r")
    workers: int = Field(1, ge=1, le=64, description="Worker processes")
    engine: EngineKind = Field(
        "auto",
        description="Where runs execute with more than one worker or a scheduler: dask "
        "(dask.distributed, extra 'cluster'), processes (a local process pool), auto (dask "
        "if installed)",
    )
    scheduler: str | None = Field(
        None,
        description="Address of a running Dask scheduler, e.g. tcp://HOST:8786 (default: a "
        "local cluster of --workers processes on 127.0.0.1)",
    )
    out: Path | None = Field(None, description="Directory for tables, figures, JSON, cache")
    trackers: list[str] = Field(["its", "lmits"], description="Trackers to compare")
    depths: list[int] = Field([1, 3, 5, 7, 9], description="Singer memory depths N")
    param: list[str] = Field(
        default_factory=list, description="Scenario parameter overrides KEY=VALUE,KEY=VALUE"
    )
    calibrate: bool = Field(
        False, description="Search ψ_init per tracker and depth for the source's false tracks"
    )
    calibration_runs: int | None = Field(
        None,
        ge=1,
        description="Runs per calibration evaluation (default: all runs, as the source)",
    )
    calibration_file: Path | None = Field(
        None, description="JSON with calibrated ψ_init (default: OUT/calibration.json if any)"
    )
    block: int = Field(10, ge=1, description="Runs per cached block (resume granularity)")
    cache: Path | None = Field(None, description="Cache directory for resuming (default OUT/cache)")
    carry_false_tracks: bool = Field(
        True, description="Carry false tracks into the next run ([thesis] §7.1); else delete all"
    )
    progress: bool | None = Field(None, description="Progress bar (default: on a terminal)")


# --------------------------------------------------------------------------------------
# tasks (top-level: they run in worker processes)
# --------------------------------------------------------------------------------------
def _block_task(exp_json: str, key: str, psi: float, start: int, stop: int, state: bytes | None):
    exp = Experiment.model_validate_json(exp_json)
    runner = pickle.loads(state) if state else VariantRunner(exp, Variant.from_key(key), psi)
    block = runner.run_many(range(start, stop))
    return key, start, stop, block.to_arrays(), pickle.dumps(runner)


def false_track_count(
    exp: Experiment,
    variant: Variant,
    psi: float,
    runs: int,
    cache: Path | None = None,
    block: int = 10,
) -> int:
    """Tracks false at confirmation (``fusion.evaluation.summary.false_at_confirmation``)
    in the first ``runs`` runs of ``variant`` with ψ_init = ``psi``; with a ``cache`` the
    runs go through the same cached blocks as :func:`run_experiment` (an evaluation at a ψ
    already run is read back, and the final run at the calibrated ψ reuses it)."""
    if cache is None:
        result = VariantRunner(exp, variant, psi).run_many(range(runs))
    else:
        result = run_variant_cached(exp, variant, psi, runs, cache, block)
    cf = false_at_confirmation(result.tracks, np.unique(result.truth.scan))
    return int(cf[-1]) if len(cf) else 0


def calibration_target(exp: Experiment, runs: int) -> tuple[float, float]:
    """(target, tolerance) of confirmed false tracks for ``runs`` runs."""
    target = exp.false_track_target * runs / SOURCE_RUNS
    return target, max(0.1 * target, 0.5)


def _calibrate_task(
    exp_json: str, key: str, runs: int, psi0: float, factor: float, cache: str | None, block: int
):
    exp = Experiment.model_validate_json(exp_json)
    variant = Variant.from_key(key)
    target, tol = calibration_target(exp, runs)
    where = Path(cache) if cache is not None else None
    res = calibrate_psi_init(
        lambda psi: false_track_count(exp, variant, psi, runs, where, block),
        target,
        tol,
        psi0=psi0,
        factor=factor,
    )
    return key, {**res.as_dict(), "runs": runs}


# --------------------------------------------------------------------------------------
# scheduling
# --------------------------------------------------------------------------------------
def dask_available() -> bool:
    """True when ``dask.distributed`` imports (the ``cluster`` extra)."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


class Engine:
    """Executes chains of tasks: ``map(fn, tasks, done_cb)`` runs ``fn(*task)`` for every
    task; ``done_cb(result)`` may return follow-up tasks (the next block of a chain).

    kind ``processes``: this process (workers = 1) or a ``ProcessPoolExecutor``; ``dask``:
    a ``distributed.Client`` of the cluster at ``scheduler``, or of a local cluster of
    ``workers`` single-threaded processes bound to 127.0.0.1 without a dashboard, started
    on first use and closed by :meth:`close`; ``auto``: dask when installed and there is
    more than one worker or a scheduler, else processes."""

    def __init__(
        self, workers: int = 1, kind: EngineKind = "processes", scheduler: str | None = None
    ) -> None:
        if kind == "auto":
            parallel = workers > 1 or scheduler is not None
            kind = "dask" if parallel and dask_available() else "processes"
        if kind == "dask" and not dask_available():
            raise RuntimeError("engine 'dask' needs dask.distributed: pip install -e '.[cluster]'")
        if scheduler is not None and kind != "dask":
            raise ValueError(f"scheduler = {scheduler!r} needs the dask engine")
        self.workers, self.kind, self.scheduler = workers, kind, scheduler
        self._client = None
        self._cluster = None

    def describe(self) -> str:
        if self.kind == "processes":
            return f"{self.workers} worker process(es)"
        where = self.scheduler or f"local cluster of {self.workers} worker(s)"
        return f"dask, {where}"

    def client(self):
        """The Dask client (connects or starts the local cluster on first call)."""
        if self._client is None:
            from distributed import Client, LocalCluster

            if self.scheduler is not None:
                self._client = Client(self.scheduler)
            else:
                self._cluster = LocalCluster(
                    n_workers=self.workers,
                    threads_per_worker=1,
                    processes=True,
                    host="127.0.0.1",
                    dashboard_address=None,
                )
                self._client = Client(self._cluster)
        return self._client

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()
        self._client = self._cluster = None

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def map(self, fn, tasks: list[tuple], done_cb) -> None:
        if self.kind == "dask":
            _map_dask(fn, tasks, self.client(), done_cb)
        else:
            _map_pool(fn, tasks, self.workers, done_cb)


def _map_pool(fn, tasks: list[tuple], workers: int, done_cb) -> None:
    """Run ``fn(*task)`` in this process (workers = 1) or in a process pool."""
    queue = list(tasks)
    if workers <= 1:
        while queue:
            queue.extend(done_cb(fn(*queue.pop(0))) or [])
        return
    with ProcessPoolExecutor(workers) as ex:
        running: set[Future] = set()
        while queue or running:
            while queue and len(running) < workers:
                running.add(ex.submit(fn, *queue.pop(0)))
            finished, running = wait(running, return_when=FIRST_COMPLETED)
            for f in finished:
                queue.extend(done_cb(f.result()) or [])


def _map_dask(fn, tasks: list[tuple], client, done_cb) -> None:
    """Run ``fn(*task)`` on a Dask cluster; follow-up tasks are submitted as results
    arrive (``pure=False``: every block is computed, never deduplicated)."""
    from distributed import as_completed

    pending = as_completed([client.submit(fn, *t, pure=False) for t in tasks])
    for fut in pending:
        for t in done_cb(fut.result()) or []:
            pending.add(client.submit(fn, *t, pure=False))


def _engine(workers: int | Engine) -> Engine:
    return workers if isinstance(workers, Engine) else Engine(workers)


def experiment_key(exp: Experiment) -> str:
    """Hash of everything that changes a run's numbers except the run count, the tracker
    list and ψ_init (which names the variant directory): the experiment, the shared
    tracker settings with their defaults, and :data:`CACHE_VERSION`."""
    d = exp.model_dump(mode="json", exclude={"runs", "trackers", "depths", "psi_init"})
    d.pop("default_psi_init")
    # the settings every variant gets (source defaults included), and the cache version
    shared = exp.tracker_config(exp.variants()[0]).model_dump(mode="json")
    d["tracker_defaults"] = {
        k: v for k, v in shared.items() if k not in ("tracker", "depth", "psi_init")
    }
    d["cache_version"] = CACHE_VERSION
    if shared["clutter"] == "known":
        d["known_clutter_version"] = KNOWN_CLUTTER_VERSION
    return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:12]


def _variant_dir(cache: Path, exp: Experiment, v: Variant, psi: float) -> Path:
    return cache / f"{exp.scenario}-{experiment_key(exp)}" / f"{v.tracker}-N{v.depth}-psi{psi:.6g}"


def _load_cached_blocks(
    vdir: Path, runs: int, block: int
) -> tuple[list[RunBlock], int, bytes | None]:
    """The complete cached blocks of runs 0, 1, … in ``vdir`` (a block's histories and the
    runner state after it): (blocks, first run not cached, that state or None)."""
    vdir.mkdir(parents=True, exist_ok=True)
    blocks: list[RunBlock] = []
    start, state = 0, None
    while start < runs:
        stop = min(start + block, runs)
        f, s = vdir / f"runs-{start:06d}-{stop:06d}.npz", vdir / f"state-{stop:06d}.pkl"
        if not (f.exists() and s.exists()):
            break
        with np.load(f) as a:
            blocks.append(RunBlock.from_arrays(dict(a)))
        state = s.read_bytes()
        start = stop
    return blocks, start, state


def _save_block(vdir: Path, start: int, stop: int, arrays: dict, state: bytes) -> None:
    """Write one block's histories, then (atomically) the runner state after it: a block
    counts as cached only when both exist."""
    np.savez_compressed(vdir / f"runs-{start:06d}-{stop:06d}.npz", **arrays)
    tmp = vdir / f"state-{stop:06d}.pkl.tmp"
    tmp.write_bytes(state)
    tmp.replace(vdir / f"state-{stop:06d}.pkl")


def run_variant_cached(
    exp: Experiment, variant: Variant, psi: float, runs: int, cache: Path, block: int = 10
) -> RunBlock:
    """Runs 0 … ``runs`` − 1 of one variant in this process, block by block through the
    cache of :func:`run_experiment` (same directories and block boundaries, so the
    results are the same numbers and each one is computed once)."""
    exp_json = exp.model_dump_json()
    vdir = _variant_dir(cache, exp, variant, psi)
    blocks, start, state = _load_cached_blocks(vdir, runs, block)
    while start < runs:
        stop = min(start + block, runs)
        _, _, _, arrays, state = _block_task(exp_json, variant.key, psi, start, stop, state)
        _save_block(vdir, start, stop, arrays, state)
        blocks.append(RunBlock.from_arrays(arrays))
        start = stop
    return RunBlock.concat(blocks)


def run_experiment(
    exp: Experiment,
    psi: dict[str, float],
    workers: int | Engine = 1,
    block: int = 10,
    cache: Path | None = None,
    advance: Advance | None = None,
) -> dict[str, RunBlock]:
    """All runs of every variant (ψ_init from ``psi`` by variant key) → RunBlock per key."""
    advance = advance or (lambda n=1: None)
    exp_json = exp.model_dump_json()
    parts: dict[str, list[RunBlock]] = {v.key: [] for v in exp.variants()}
    tasks = []
    for v in exp.variants():
        start, state = 0, None
        if cache is not None:
            vdir = _variant_dir(cache, exp, v, psi[v.key])
            loaded, start, state = _load_cached_blocks(vdir, exp.runs, block)
            parts[v.key].extend(loaded)
            for first in range(0, start, block):
                advance(min(block, start - first))
        if start < exp.runs:
            tasks.append((exp_json, v.key, psi[v.key], start, min(start + block, exp.runs), state))

    def done(result):
        key, start, stop, arrays, state = result
        v = Variant.from_key(key)
        parts[key].append(RunBlock.from_arrays(arrays))
        if cache is not None:
            _save_block(_variant_dir(cache, exp, v, psi[key]), start, stop, arrays, state)
        advance(stop - start)
        if stop < exp.runs:
            return [(exp_json, key, psi[key], stop, min(stop + block, exp.runs), state)]
        return []

    _engine(workers).map(_block_task, tasks, done)
    return {k: RunBlock.concat(sorted(p, key=lambda b: int(b.runs[0]))) for k, p in parts.items()}


#: Bracketing factor of a calibration that starts from an earlier calibrated ψ_init (at
#: 100 runs the sampling error of ψ_init is about ×/÷ 1.66 at b ≈ 1, see
#: :func:`fusion.evaluation.calibration.sampling_interval`), and from the default ψ_init.
WARM_FACTOR, COLD_FACTOR = 2.0, 4.0


def calibrate(
    exp: Experiment,
    runs: int,
    workers: int | Engine = 1,
    advance: Advance | None = None,
    *,
    start: dict[str, float] | None = None,
    cache: Path | None = None,
    block: int = 10,
    on_result: Callable[[str, dict], None] | None = None,
) -> dict[str, dict]:
    """Calibrated ψ_init per variant key (``Calibration.as_dict`` entries).

    ``start``: ψ_init to start from per key (an earlier calibration, searched with the
    narrower :data:`WARM_FACTOR`); ``cache``: evaluations go through the run cache (a
    repeated or interrupted calibration re-reads what it evaluated, and the experiment's
    runs at the calibrated ψ are read back instead of run again) — not with a remote Dask
    scheduler, whose workers may not see this machine's directory; ``on_result(key,
    value)`` is called as each variant finishes (to save it)."""
    advance = advance or (lambda n=1: None)
    start = start or {}
    exp_json = exp.model_dump_json()
    engine = _engine(workers)
    where = None if cache is None or engine.scheduler is not None else str(cache)
    out: dict[str, dict] = {}
    tasks = []
    for v in exp.variants():
        psi0 = start.get(v.key)
        factor = WARM_FACTOR if psi0 is not None else COLD_FACTOR
        psi0 = min(max(psi0, 1e-6), 0.5) if psi0 is not None else exp.psi_for(v)
        tasks.append((exp_json, v.key, runs, psi0, factor, where, block))

    def done(result):
        out[result[0]] = result[1]
        if on_result is not None:
            on_result(*result)
        advance(1)
        return []

    engine.map(_calibrate_task, tasks, done)
    return {v.key: out[v.key] for v in exp.variants()}


# --------------------------------------------------------------------------------------
# outputs
# --------------------------------------------------------------------------------------
def evaluate(
    exp: Experiment,
    *,
    workers: int | Engine = 1,
    block: int = 10,
    cache: Path | None = None,
    calibration: dict[str, dict] | None = None,
    advance: Advance | None = None,
) -> dict:
    """Run the experiment and summarise: rows (retention keys + extras), curves per variant
    key, the configuration of every variant and the calibration used."""
    cal = calibration or {}
    psi = {
        v.key: float(cal[v.key]["psi_init"]) if v.key in cal else exp.psi_for(v)
        for v in exp.variants()
    }
    t0 = time.perf_counter()
    blocks = run_experiment(exp, psi, workers, block, cache, advance)
    rows, curves, configs = [], {}, {}
    for v in exp.variants():
        s = summarise(blocks[v.key], exp, v, psi[v.key])
        rows.append(s["row"])
        curves[v.key] = s["curves"]
        configs[v.key] = exp.tracker_config(v, psi[v.key]).model_dump(mode="json")
    return {
        "scenario": exp.scenario,
        "rows": rows,
        "row_keys": list(ROW_KEYS),
        "curves": curves,
        "experiment": exp.model_dump(mode="json"),
        "tracker_configs": configs,
        "calibration": cal,
        "false_track_target_per_500_runs": exp.false_track_target,
        "elapsed_s": round(time.perf_counter() - t0, 2),
        "machine": {"cpus": os.cpu_count(), "engine": _engine(workers).describe()},
    }


#: Summary fields that are measurements of this machine, not results of the runs.
MEASURED_FIELDS = ("elapsed_s", "calibration_s", "runs_s", "machine")


def results_digest(summary: dict) -> str:
    """SHA-256 (16 hex) of the summary without the CPU and wall-clock measurements
    (``MEASURED_FIELDS``, every row's ``cpu_s`` and ``cpu_ms_per_run``): equal for any
    engine, worker count or block size (the numbers depend on the experiment and ψ_init)."""
    d = {k: v for k, v in summary.items() if k not in MEASURED_FIELDS}
    d["rows"] = [
        {k: v for k, v in r.items() if k not in ("cpu_s", "cpu_ms_per_run")}
        for r in summary["rows"]
    ]
    return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


def retention_table(summary: dict) -> str:
    """Markdown retention table plus ψ_init, runs and confirmed false tracks."""
    rows = summary["rows"]
    table = retention_markdown(rows)
    extra = ["| tracker | depth | ψ_init | runs | confirmed false (all) | false at confirmation | "
             "per 500 runs | CPU ms/run | GOSPA (m) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]  # fmt: skip
    for r in rows:
        extra.append(
            f"| {r['tracker']} | {r['depth']} | {r['psi_init']:.4g} | {r['runs']} | "
            f"{r['false_tracks']} | {r['false_at_confirmation']} | "
            f"{r['false_at_confirmation_per_500_runs']:.1f} | "
            f"{r['cpu_ms_per_run']:.0f} | {r['gospa_mean']:.1f} |"
        )
    return table + "\n" + "\n".join(extra) + "\n"


def write_figures(summary: dict, out: Path, tag: str) -> list[Path]:
    """CTT, cumulative confirmed false tracks, RMSE with its PCRLB floors (dotted: the
    ``pcrlb_m`` curve of :mod:`fusion.evaluation.bound` per variant; dash-dot grey:
    ``pcrlb_all_detected_m`` of the first variant) and GOSPA per scan (one PNG each)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    specs = [
        ("ctt", "ctt_percent", "confirmed true tracks (% of targets)"),
        ("false-tracks", "false_tracks_cumulative", "confirmed false tracks (cumulative)"),
        (
            "false-at-confirmation",
            "false_at_confirmation_cumulative",
            "tracks false at confirmation (cumulative)",
        ),
        ("rmse", "rmse_m", "RMSE of confirmed true tracks (m)"),
        ("gospa", "gospa_m", f"GOSPA (c = {summary['experiment']['gospa_c']:g} m, p = 2) (m)"),
    ]
    paths = []
    runs = summary["rows"][0]["runs"] if summary["rows"] else 0
    for name, key, ylabel in specs:
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for i, (vk, c) in enumerate(summary["curves"].items()):
            y = np.array([np.nan if v is None else v for v in c[key]], float)
            style = "-" if vk.startswith("lm") else "--"
            ax.plot(c["scans"], y, style, color=f"C{i % 10}", lw=1.5, label=vk.replace(":", " N="))
            if name == "rmse" and "pcrlb_m" in c:
                f = np.array([np.nan if v is None else v for v in c["pcrlb_m"]], float)
                ax.plot(c["scans"], f, ":", color=f"C{i % 10}", lw=1.0)
        if name == "rmse" and summary["curves"]:
            c = next(iter(summary["curves"].values()))
            ax.plot([], [], ":", color="0.3", lw=1.0, label="PCRLB, P_D factor (dotted)")
            if "pcrlb_all_detected_m" in c:
                f = np.array([np.nan if v is None else v for v in c["pcrlb_all_detected_m"]])
                ax.plot(c["scans"], f, "-.", color="0.5", lw=0.8, label="PCRLB, P_D = 1")
        ax.set_xlabel("scan")
        ax.set_ylabel(ylabel)
        ax.set_title(f"{summary['scenario']}, {runs} runs")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, ncol=2)
        fig.tight_layout()
        p = out / f"{tag}-{name}.png"
        fig.savefig(p, dpi=100)
        plt.close(fig)
        paths.append(p)
    return paths


def load_calibration(path: Path, exp: Experiment) -> dict[str, dict]:
    """Calibrated values of a calibration JSON matching the experiment's scenario."""
    d = json.loads(Path(path).read_text())
    if d.get("scenario") != exp.scenario:
        raise ValueError(
            f"calibration file {str(path)!r}: scenario {d.get('scenario')!r}, the experiment "
            f"is {exp.scenario!r}"
        )
    return d.get("variants", {})


def save_calibration(path: Path, exp: Experiment, runs: int, values: dict[str, dict]) -> None:
    """Merge ``values`` into the calibration JSON at ``path``."""
    old = {}
    if path.exists():
        try:
            old = load_calibration(path, exp)
        except (ValueError, json.JSONDecodeError):
            old = {}
    old.update(values)
    doc = {
        "scenario": exp.scenario,
        "seed": exp.seed,
        "calibration_runs": runs,
        "target_per_500_runs": exp.false_track_target,
        "experiment_key": experiment_key(exp),
        "variants": old,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=1))


# --------------------------------------------------------------------------------------
# command
# --------------------------------------------------------------------------------------
def _tracker_settings(args) -> tuple[dict, float | None]:
    """TrackerConfig fields given as flags (or in the --config [tracker] table), minus the
    ones the experiment sets per variant; and ψ_init if given (the default ψ_init)."""
    from skyfuse.fusion.tracker import TrackerConfig
    from skyfuse.services.runtime.config import load_toml

    given: dict = {}
    if getattr(args, "config", None) is not None:
        given.update(load_toml(args.config, "tracker"))
    given.update({k: v for k, v in vars(args).items() if k in TrackerConfig.model_fields})
    psi = given.pop("psi_init", None)
    for k in ("tracker", "depth"):
        given.pop(k, None)
    return given, psi


def run_tracker_eval(args) -> int:
    """``skyfuse eval SCENARIO --trackers ...`` (see :mod:`services.cmd_eval`): one engine
    (process pool or Dask cluster) for the calibration and the runs."""
    from skyfuse.services.runtime.config import ConfigError, build_config

    cfg = build_config(TrackerEvalConfig, args)
    try:
        engine = Engine(cfg.workers, cfg.engine, cfg.scheduler)
    except (RuntimeError, ValueError) as e:
        raise ConfigError(f"engine: {e}") from None
    with engine:
        return _tracker_eval(args, cfg, engine)


def warm_start(path: Path | None, exp: Experiment) -> dict[str, float]:
    """ψ_init per variant key of an earlier calibration of the same scenario at ``path``
    (any run count, possibly older settings), to start a calibration from; empty when
    there is none. Only the starting point of the search: the result is searched to the
    tolerance on this experiment's runs whatever it starts from."""
    if path is None or not path.exists():
        return {}
    try:
        return {k: float(c["psi_init"]) for k, c in load_calibration(path, exp).items()}
    except (ValueError, TypeError, KeyError, json.JSONDecodeError):
        return {}


def _calibration(
    cfg: TrackerEvalConfig,
    exp: Experiment,
    engine: Engine,
    cal_path: Path | None,
    cache: Path | None = None,
) -> dict[str, dict]:
    """ψ_init per variant key: calibrated (``--calibrate``, each variant saved to
    ``cal_path`` as it finishes, starting from the ψ_init already there), read from
    ``cal_path`` if it exists, else empty (the experiment's ψ_init)."""
    from skyfuse.services.runtime.config import ConfigError
    from skyfuse.services.runtime.progress import progress_bar

    variants = exp.variants()
    calibration: dict[str, dict] = {}
    if cfg.calibrate:
        runs_c = cfg.calibration_runs or exp.runs
        target, tol = calibration_target(exp, runs_c)
        start = warm_start(cal_path, exp)
        print(f"calibrating ψ_init on {runs_c} runs: {target:.2f} ± {tol:.2f} false tracks"
              + (f" (from the ψ_init in {cal_path})" if start else ""))  # fmt: skip

        def save(key: str, value: dict) -> None:
            if cal_path is not None:
                save_calibration(cal_path, exp, runs_c, {key: value})

        with progress_bar("calibration", len(variants), enabled=cfg.progress) as advance:
            calibration = calibrate(
                exp, runs_c, engine, advance, start=start, cache=cache, block=cfg.block,
                on_result=save,
            )  # fmt: skip
        for k, c in calibration.items():
            note = "" if c["converged"] else ", NOT converged"
            ci = c.get("psi_interval_95")
            err = f", 95 % [{ci[0]:.3g}, {ci[1]:.3g}]" if ci else ", sampling error unknown"
            print(
                f"  {k}: ψ_init = {c['psi_init']:.4g}{err}, {c['false_tracks']:g} false "
                f"tracks ({len(c['evaluations'])} evaluations{note})"
            )
        if cal_path is not None:  # every variant was saved as it finished (``save``)
            print(f"wrote {cal_path}")
    elif cal_path is not None and cal_path.exists():
        try:
            calibration = load_calibration(cal_path, exp)
        except (ValueError, json.JSONDecodeError) as e:
            raise ConfigError(f"calibration_file: {e}") from None
        calibration = {v.key: calibration[v.key] for v in variants if v.key in calibration}
        if calibration:
            print(f"ψ_init from {cal_path}: " + ", ".join(
                f"{k} {c['psi_init']:.4g}" for k, c in calibration.items()))  # fmt: skip
    return calibration


def _tracker_eval(args, cfg: TrackerEvalConfig, engine: Engine) -> int:
    from pydantic import ValidationError
    from skyfuse.fusion.sim import build_scenario
    from skyfuse.services.runtime.config import (
        ConfigError,
        format_validation_error,
        parse_key_values,
    )
    from skyfuse.services.runtime.progress import progress_bar

    settings, psi = _tracker_settings(args)
    try:
        exp = Experiment(
            scenario=cfg.scenario,
            scenario_params=parse_key_values(cfg.param),
            trackers=cfg.trackers,
            depths=cfg.depths,
            runs=cfg.runs,
            seed=cfg.seed,
            tracker_settings=settings,
            carry_false_tracks=cfg.carry_false_tracks,
            **({"default_psi_init": psi} if psi is not None else {}),
        )
        for v in exp.variants():
            exp.tracker_config(v)
    except ValidationError as e:
        raise ConfigError(format_validation_error(e)) from None
    try:
        build_scenario(exp.scenario, seed=exp.seed, **exp.scenario_params)
    except (ValueError, TypeError) as e:  # a scenario parameter, named by the builder
        raise ConfigError(f"param: {e}") from None
    out = cfg.out
    cache = cfg.cache or (out / "cache" if out is not None else None)
    variants = exp.variants()
    tag = exp.scenario
    t0 = time.perf_counter()
    print(
        f"{exp.scenario}: {exp.runs} runs, seed {exp.seed}, variants "
        f"{', '.join(v.key for v in variants)}, {engine.describe()}",
        flush=True,
    )
    cal_path = cfg.calibration_file or (out / "calibration.json" if out is not None else None)
    t_cal = time.perf_counter()
    calibration = _calibration(cfg, exp, engine, cal_path, cache)
    t_cal = time.perf_counter() - t_cal
    total = exp.runs * len(variants)
    with progress_bar(f"eval {tag}", total, enabled=cfg.progress) as advance:
        summary = evaluate(
            exp,
            workers=engine,
            block=cfg.block,
            cache=cache,
            calibration=calibration,
            advance=advance,
        )
    elapsed = time.perf_counter() - t0
    summary["elapsed_s"] = round(elapsed, 2)
    summary["calibration_s"] = round(t_cal, 2)
    summary["runs_s"] = round(elapsed - t_cal, 2)
    table = retention_table(summary)
    print(table)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / f"{tag}-retention.md").write_text(table)
        (out / f"{tag}.json").write_text(json.dumps(summary, indent=1))
        for p in write_figures(summary, out, tag):
            print(f"wrote {p}")
    json_out = getattr(args, "json_out", None)
    if json_out:
        Path(json_out).parent.mkdir(parents=True, exist_ok=True)
        Path(json_out).write_text(json.dumps(summary, indent=1))
        print(f"wrote {json_out}")
    print(f"results digest {results_digest(summary)} (equal for any engine and workers)")
    print(f"elapsed {elapsed:.1f} s")
    return 0
