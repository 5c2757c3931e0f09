"""``skyfuse eval SCENARIO ...``: Monte Carlo evaluation of skyfuse on a named scenario.

Scenarios are dispatched by name through :data:`EVALUATORS`; each evaluator registers its
own options. Supported now:

* ``crossing-4g`` — [MZD] §2, §4: two targets crossing with opposite 4 g turns, one
  2-D radar, σ_r = 20 m, σ_θ 2.5 or 6 mrad, GNN association with the filters compared in
  the source (PCWPA KF, Singer KF, two-model IMM), plus the IMM with p22 = 0.9 and the
  three-model CV/Singer/CT IMM. Reports the position RMSE per scan per filter, the number
  of runs in which the two tracks swap, and the run configuration.

    skyfuse eval crossing-4g --filters kf,singer,imm2 --runs 300 --sigma-az-mrad 2.5 \\
        --seed 1 --out DIR [--json FILE]

Every filter sees the same simulated plots in a run (seed + run index).

* ``thesis-stt``, ``thesis-mtt-5/15/50``, ``lm-ipf-2/15`` — the existence trackers'
  Monte Carlo evaluation of [thesis] ch. 7
  (:mod:`skyfuse.services.evaluation.montecarlo`): retention table (Markdown + JSON rows
  ``tracker``, ``depth``, ``nCases``, ``nOK``, ``nSwitched``,
  ``nLost``, ``merged``, ``cpu_s``), CTT / false-track / RMSE / GOSPA curves (PNG), the
  full configuration, optional ψ_init calibration; resumable from ``--out``.

    skyfuse eval thesis-mtt-5 --trackers its,lmits --depths 1,7 --runs 50 --seed 1 \
        [--calibrate] [--workers 2] --out DIR [--json FILE] [--q 0.75 ...]

* ``--reference REF`` — the tracks scored against an independent reference, an ADS-B
  (CAT021) or multilateration (CAT010) recording not given to the tracker
  (:mod:`skyfuse.services.evaluation.reference_eval`): probability of update, horizontal
  position error, track ids per aircraft, duplicates, false tracks and correct
  identification, surface and airborne. The tracks: those of FILE (below), the
  TrackBatch messages of a recording (``--tracks T.mcap``) or a CAT010 sensor's own
  tracks (``--sensor-tracks S.ast``: the sensor alone).

    skyfuse eval --sensor-tracks mlat.ast --reference adsb.ast --sites lebl.toml \
        --date 2016-05-10 [--reference-time-offset auto] [--json FILE]
    skyfuse eval --tracks t.mcap --reference adsb.ast --reference-date 2016-05-10

* ``FILE.mcap`` / ``FILE.pcap`` / ``FILE.ast`` — a recording (simulated: Truth messages
  and plot ``target_id``; real: Mode-S addresses on plots; ASTERIX with ``--sites``)
  through one tracker by the offline runner (:mod:`skyfuse.services.evaluation.recording`):
  completeness, track-id changes, confirmed false tracks per hour, time to confirm, and
  with truth GOSPA over time, truth coverage and position RMSE.

    skyfuse eval r.mcap --tracker lmits --depth 3 [--config fusion.toml] --json FILE
    skyfuse eval rec.pcap --sites sites.toml --date 2024-05-17 --tracker lmits
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections.abc import Callable
from pathlib import Path

from skyfuse.services.evaluation.crossing import (
    CrossingEvalConfig,
    evaluate_crossing,
    markdown_table,
    scenario_params,
    write_figures,
)
from skyfuse.services.runtime.config import (
    ConfigError,
    add_json_argument,
    add_model_arguments,
    build_config,
)

EVALUATORS: dict[str, Callable[[argparse.Namespace], int]] = {}


def register(sub: argparse._SubParsersAction) -> None:
    from skyfuse.fusion.tracker import TrackerConfig
    from skyfuse.services.evaluation.montecarlo import TrackerEvalConfig

    p = sub.add_parser(
        "eval",
        help="Monte Carlo evaluation on a named scenario, of a recording (FILE.mcap), or of "
        "tracks against a reference (--reference)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_model_arguments(p, CrossingEvalConfig, skip=("scenario",))
    p.add_argument(
        "scenario", nargs="*", default=argparse.SUPPRESS,
        help="Scenario to evaluate (crossing-4g, thesis-*, lm-ipf-*) or a recording FILE "
        "(several ASTERIX files of different sensors are merged in time order; omit it with "
        "--tracks or --sensor-tracks)",
    )  # fmt: skip
    g = p.add_argument_group("tracker evaluation (thesis-*, lm-ipf-* scenarios)")
    add_model_arguments(g, TrackerEvalConfig, skip=SHARED_FIELDS)
    t = p.add_argument_group(
        "tracker settings (scenario runs: override the source's settings; FILE.mcap: the tracker)"
    )
    add_model_arguments(t, TrackerConfig, skip=("p_gate", "imm_gating"))
    r = p.add_argument_group("ASTERIX recordings (FILE.ast, FILE.pcap)")
    r.add_argument(
        "--sites", type=Path, default=None, help="Sites TOML ([[radar]] sac, sic, lat, lon, alt)"
    )
    r.add_argument(
        "--date",
        default=None,
        help="UTC date of the first record, YYYY-MM-DD (default: pcap capture time, else today)",
    )
    r.add_argument(
        "--report-window", type=float, default=1.0,
        help="Batch window of report sensors without update-cycle messages (ADS-B), s "
        "(default: 1.0)",
    )  # fmt: skip
    r.add_argument(
        "--adsb-sigma", type=float, default=None,
        help="σ per axis of every ADS-B position, m (an empirical figure; default: the one its "
        "NACp/NUCp gives)",
    )  # fmt: skip
    from skyfuse.fusion.metrics.reference_scores import ReferenceScoreConfig
    from skyfuse.services.evaluation.reference_eval import ReferenceEvalOptions

    ref = p.add_argument_group(
        "scoring against a reference (ADS-B or multilateration: --reference REF; "
        "tracks of FILE, of --tracks T.mcap or of --sensor-tracks S.ast)"
    )
    add_model_arguments(ref, ReferenceEvalOptions)
    add_model_arguments(ref, ReferenceScoreConfig)
    from skyfuse.services.fusion.registration_link import add_registration_arguments

    add_registration_arguments(p)
    p.add_argument(
        "--config", type=Path, default=None,
        help="TOML file with a [tracker] (and [registration]) table",
    )  # fmt: skip
    add_json_argument(
        p, "Write the summary (tables, curves, configuration) as JSON to FILE", default=None
    )
    p.set_defaults(func=run)


#: Options of the crossing evaluator also used by the tracker evaluation.
SHARED_FIELDS = ("scenario", "runs", "seed", "out", "workers")


def _first_file(args: argparse.Namespace) -> None:
    """``scenario`` as its first value (a name or a recording), the other recordings in
    ``more_files``."""
    given = getattr(args, "scenario", None)
    if isinstance(given, list):
        args.more_files = [Path(f) for f in given[1:]]
        if given:
            args.scenario = given[0]
        else:
            del args.scenario


def run(args: argparse.Namespace) -> int:
    from skyfuse.fusion.evaluation import PLANAR_SCENARIOS

    _first_file(args)
    name = getattr(args, "scenario", None)
    if getattr(args, "tracks", None) is not None or getattr(args, "sensor_tracks", None):
        if name is not None:
            raise ConfigError(
                f"scenario = {name!r}: --tracks / --sensor-tracks score existing tracks; "
                "give no scenario or recording with them"
            )
        from skyfuse.services.evaluation.reference_eval import run_reference

        return run_reference(args)
    if name is None:
        raise ConfigError(
            "give a scenario (crossing-4g, thesis-*, lm-ipf-*), a recording FILE, or "
            "--tracks T.mcap / --sensor-tracks S.ast with --reference REF"
        )
    if getattr(args, "more_files", None) and not Path(name).is_file():
        raise ConfigError(f"scenario = {name!r}: several inputs are recording files only")
    if name is not None and (name.endswith(".mcap") or Path(name).is_file()):
        from skyfuse.services.evaluation.recording import run_recording

        return run_recording(args)
    if name in PLANAR_SCENARIOS:
        from skyfuse.services.evaluation.montecarlo import run_tracker_eval

        return run_tracker_eval(args)
    if name not in EVALUATORS:
        raise ConfigError(
            f"scenario = {name!r}: skyfuse eval supports {', '.join(sorted(EVALUATORS))}, "
            f"{', '.join(PLANAR_SCENARIOS)} or a recording FILE.mcap (for other scenarios: "
            "skyfuse simulate NAME --out r.mcap, then skyfuse eval r.mcap)"
        )
    return EVALUATORS[name](args)


def run_crossing(args: argparse.Namespace) -> int:
    cfg = build_config(CrossingEvalConfig, args)
    tag = f"{cfg.sigma_az_mrad:g}mrad"
    t0 = time.perf_counter()
    step = max(1, cfg.runs // 10)

    def progress(done: int) -> None:
        if done % step == 0 or done == cfg.runs or cfg.workers > 1:
            print(f"  {done}/{cfg.runs} runs, {time.perf_counter() - t0:.1f} s", flush=True)

    print(
        f"crossing-4g: {cfg.runs} runs, σ_θ = {cfg.sigma_az_mrad} mrad, filters "
        f"{','.join(cfg.filters)}, {cfg.workers} worker(s)"
    )
    summary, results = evaluate_crossing(cfg, progress)
    elapsed = time.perf_counter() - t0
    config = cfg.model_dump(mode="json")
    config["scenario_parameters"] = {
        k: (v if isinstance(v, (int, float, str, bool)) else str(v))
        for k, v in scenario_params(cfg).items()
    }
    summary["config"] = config
    summary["elapsed_s"] = round(elapsed, 2)
    summary["machine"] = {"cpus": os.cpu_count()}
    table = markdown_table(summary)
    print(table)
    if cfg.out is not None:
        cfg.out.mkdir(parents=True, exist_ok=True)
        (cfg.out / f"crossing-4g-{tag}.md").write_text(table)
        for path in write_figures(summary, results, cfg.out, tag):
            print(f"wrote {path}")
        if args.json_out is None:
            (cfg.out / f"crossing-4g-{tag}.json").write_text(json.dumps(summary, indent=1))
    if args.json_out:
        Path(args.json_out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json_out).write_text(json.dumps(summary, indent=1))
        print(f"wrote {args.json_out}")
    print(f"elapsed {elapsed:.1f} s")
    return 0


EVALUATORS["crossing-4g"] = run_crossing
