"""``skyfuse eval FILE --tracker ...``: evaluate one tracker on a recording (MCAP, or
ASTERIX CAT048/CAT034 in a pcap or raw ``.ast`` file with a sites file).

The recording goes through :func:`~skyfuse.services.evaluation.offline.run_offline` —
the code path of ``skyfuse track`` and of the live fusion service — with the scoring
observers of :mod:`~skyfuse.services.evaluation.observers`:

* **plot labels** (``labels``): simulated recordings carry each plot's origin
  ``target_id`` (−1 for clutter); real recordings the Mode-S address (I048/220). Each plot
  gets the track whose most likely plot it was (``TrackerOutput.assigned_plot``) and that
  track's confirmation state; the label metrics are completeness, track-id changes per
  aircraft, confirmed false tracks per hour and the mean time to confirm.
* **Truth messages** (simulated recordings, ``truth``): at every Truth time the confirmed
  tracks of the latest output, predicted (constant velocity) to that time, against the
  targets inside coverage (the :class:`~skyfuse.services.evaluation.observers.Coverage`
  rule): GOSPA (order p, cut-off c, α = 2, with the track-switch term) over time, truth
  coverage and position RMSE.
* **sensor registration** (``registration_vs_truth``, recordings whose truth carries
  radar biases, ``skyfuse simulate --param ID.bias_*``): the bias estimates against the
  truth over time and at the end, duplicate confirmed tracks per aircraft
  (:mod:`~skyfuse.services.evaluation.registration_eval`); the same recording is then run
  again with registration off (``registration_off``: RMSE, coverage, GOSPA, duplicates).
* **traffic classes** (``labels_by_traffic``): the label measures separately for
  airborne (FL ≥ 10, ≥ 2 NM), surface (FL < 10) and overhead traffic, and for all.
* **an independent reference** (``reference``, with ``--reference REF``: ADS-B or
  multilateration): the tracks scored against it
  (:mod:`~skyfuse.services.evaluation.reference_eval`).
"""

from __future__ import annotations

import logging
from pathlib import Path

from pydantic import Field
from skyfuse.schemas import FrameKind
from skyfuse.services.asterix.read_options import AsterixReadOptions

log = logging.getLogger(__name__)


class RecordingEvalOptions(AsterixReadOptions):
    """Evaluation options of a recording (the tracker is a ``TrackerConfig``)."""

    frame_kind: FrameKind = Field(FrameKind.STEREOGRAPHIC, description="System frame")
    gospa_c: float = Field(500.0, gt=0, description="GOSPA cut-off c, m")
    gospa_p: float = Field(2.0, ge=1, description="GOSPA order p")
    switch_penalty: float = Field(0.0, ge=0, description="GOSPA switch penalty γ, m")
    coverage_window: float = Field(15.0, gt=0, description="Target seen if a plot within, s")
    min_detections: int = Field(3, ge=1, description="Detections before a target is seen")
    warmup_s: float | None = Field(
        None,
        ge=0,
        description="Aircraft first seen earlier: no time-to-confirm, s (default: 0 for MCAP, "
        "60 for ASTERIX)",
    )
    min_label_share: float = Field(0.5, gt=0, le=1, description="Label share of a true track")
    assumed_altitude: float | None = Field(
        None,
        ge=-1000,
        le=30000,
        description="Height of plots without one, m, ± 3000 m (default: the site's height)",
    )
    compare_registration: bool = Field(
        True,
        description="When the truth carries radar biases and registration is not off, "
        "run again with registration off and report its RMSE and duplicates",
    )


def _truth_observers(opts: RecordingEvalOptions) -> list:
    """The truth GOSPA/RMSE observer and the registration-vs-truth observer on it."""
    from skyfuse.services.evaluation import observers as obs
    from skyfuse.services.evaluation.registration_eval import RegistrationObserver

    truth = obs.TruthObserver(
        obs.Coverage(opts.coverage_window, opts.min_detections),
        c=opts.gospa_c,
        p=opts.gospa_p,
        switch_penalty=opts.switch_penalty,
    )
    return [truth, RegistrationObserver(truth)]


def evaluate_recording(
    path: str | Path,
    tcfg=None,
    opts: RecordingEvalOptions | None = None,
    *,
    sites=None,
    date=None,
    registration=None,
    reference=None,
) -> dict:
    """Run ``tcfg`` (a ``TrackerConfig``, default its defaults) over the recording at
    ``path``; return the summary dict (``labels``, ``labels_by_traffic``, ``truth`` when
    the recording has Truth messages, ``registration_vs_truth``, ``timing``, counts).
    ``registration``: a RegistrationConfig (default on). ``sites``, ``date``: ASTERIX
    input only (see :func:`~skyfuse.services.evaluation.inputs.open_input`).
    ``reference``: a :class:`~skyfuse.services.evaluation.observers.ReferenceObserver`
    (it also gets the recording's sites). Raises ``InputError``."""
    from skyfuse.fusion.tracker import TrackerConfig
    from skyfuse.services.evaluation import observers as obs
    from skyfuse.services.evaluation.inputs import is_mcap, open_input
    from skyfuse.services.evaluation.offline import OfflineConfig, run_offline

    opts = opts or RecordingEvalOptions()
    tcfg = tcfg if tcfg is not None else TrackerConfig()
    paths = [Path(p) for p in path] if isinstance(path, (list, tuple)) else [Path(path)]
    if reference is not None and paths[0].is_file() and is_mcap(paths[0]):
        sites = date = None  # given for the reference (its sites, its date) only
    src = open_input(paths, sites_file=sites, date=date, sector_count=opts.sector_count,
                     report_window=opts.report_window, adsb_sigma=opts.adsb_sigma)  # fmt: skip
    asterix = src.asterix is not None
    warmup = opts.warmup_s if opts.warmup_s is not None else (60.0 if asterix else 0.0)
    truth_obs, reg_obs = _truth_observers(opts)
    observers = [
        obs.LabelObserver(warmup_s=warmup, min_label_share=opts.min_label_share),
        truth_obs,
        reg_obs,
        obs.Timing(),
    ]
    if reference is not None:
        reference.sites = {**src.sites_in_file, **reference.sites}
        observers.append(reference)
    ocfg = OfflineConfig(
        tracker=tcfg,
        frame_kind=opts.frame_kind,
        assumed_altitude=opts.assumed_altitude,
        registration=registration,
    )
    result = run_offline(src.messages(), src.sites, ocfg, observers)
    files = ", ".join(map(str, paths))
    summary = {"file": files, "tracker": tcfg.tracker, "depth": tcfg.memory_depth}
    summary.update(result.summary())
    mode = registration.mode if registration is not None else "on"
    if opts.compare_registration and reg_obs.truth and mode != "off":
        summary["registration_off"] = _without_registration(paths, ocfg, opts, sites, date)
    summary["recording_rejected"] = dict(src.stats.rejected)
    if asterix:
        summary["asterix"] = {"radars": src.asterix.radars, "counts": src.asterix.stats}
    summary["config"] = tcfg.model_dump(mode="json")
    summary["options"] = opts.model_dump(mode="json")
    return summary


def _without_registration(path, ocfg, opts, sites, date) -> dict:
    """The truth scores of a second pass with registration off (the same input)."""
    from skyfuse.fusion.registration import RegistrationConfig
    from skyfuse.services.evaluation.inputs import open_input
    from skyfuse.services.evaluation.offline import run_offline

    src = open_input(path, sites_file=sites, date=date, sector_count=opts.sector_count,
                     report_window=opts.report_window, adsb_sigma=opts.adsb_sigma)  # fmt: skip
    base = ocfg.registration or RegistrationConfig()
    off = ocfg.model_copy(update={"registration": base.model_copy(update={"mode": "off"})})
    truth, reg = _truth_observers(opts)
    run_offline(src.messages(), src.sites, off, [truth, reg])
    t = truth.summary().get("truth", {})
    return {
        "position_rmse_m": t.get("position_rmse_m"),
        "coverage": t.get("coverage"),
        "gospa_mean_m": (t.get("gospa") or {}).get("mean_m"),
        "duplicates": reg.duplicates(),
    }


def run_recording(args) -> int:
    """``skyfuse eval FILE``: tracker from ``--config`` [tracker] and the flags."""
    from skyfuse.fusion.tracker import TrackerConfig
    from skyfuse.services.evaluation.inputs import InputError
    from skyfuse.services.evaluation.reference_eval import print_table
    from skyfuse.services.evaluation.report import STDOUT, write_summary
    from skyfuse.services.fusion.registration_link import registration_config
    from skyfuse.services.runtime.config import ConfigError, build_config

    tcfg = build_config(
        TrackerConfig,
        args,
        toml_path=getattr(args, "config", None),
        section="tracker",
        env_prefix="SKYFUSE_TRACKER_",
    )
    opts = RecordingEvalOptions(
        report_window=getattr(args, "report_window", 1.0),
        adsb_sigma=getattr(args, "adsb_sigma", None),
    )
    try:
        reference = _reference_observer(args)
        summary = evaluate_recording(
            [args.scenario, *getattr(args, "more_files", [])],
            tcfg,
            opts,
            sites=getattr(args, "sites", None),
            date=getattr(args, "date", None),
            registration=registration_config(args, toml_path=getattr(args, "config", None)),
            reference=reference,
        )
    except InputError as e:
        if e.usage:
            raise ConfigError(str(e)) from None
        log.error("%s", e)
        return 1
    json_out = getattr(args, "json_out", None)
    if reference is not None and (json_out is None or str(json_out) != STDOUT):
        name = " + ".join(Path(f).name for f in [args.scenario, *getattr(args, "more_files", [])])
        print_table(summary["reference"], f"{name} ({tcfg.tracker}) against "
                    f"{reference.reference.path.name}")  # fmt: skip
    write_summary(summary, json_out)
    return 0


def _reference_observer(args):
    """The ReferenceObserver of ``--reference`` (None without it); InputError."""
    from skyfuse.fusion.metrics.reference_scores import ReferenceScoreConfig
    from skyfuse.services.evaluation.observers import ReferenceObserver
    from skyfuse.services.evaluation.reference_eval import (
        ReferenceEvalOptions,
        load_site_map,
        open_reference,
    )
    from skyfuse.services.runtime.config import build_config

    opts = build_config(ReferenceEvalOptions, args)
    if opts.reference is None:
        return None
    ref = open_reference(opts, getattr(args, "date", None))
    sites = load_site_map(getattr(args, "sites", None))
    cfg = build_config(ReferenceScoreConfig, args)
    from skyfuse.services.evaluation.reference_area import read_score_area

    area = read_score_area(opts.score_area)
    return ReferenceObserver(ref, sites, cfg, opts.reference_time_offset, area=area)
