"""``skyfuse track FILE.mcap|FILE.pcap|FILE.ast|--sample``: run the tracker offline over a
recording.

The recording goes through the offline runner
(:func:`skyfuse.services.evaluation.offline.run_offline`): its radar sites
(``skyfuse/@v1/radar/*/site``) and plot batches (``…/plots``), in time order, through the
same pipeline as the live fusion service (convert to the system frame → tracker →
TrackBatch/TrackEvent), with the frame placed by the live service's rule (the sites'
mean at the first plot batch). Tracks and events go to an MCAP file on
``skyfuse/@v1/fusion/{id}/tracks`` and ``…/events``. The summary (one line on stdout;
the whole of it with ``--json FILE``, or on stdout with ``--json`` alone) holds the
plots and batches processed, the label scores of the tracks (``labels``: the plots'
simulation ``target_id`` or, in real data, Mode-S addresses: completeness, track-id
changes, confirmed false tracks per hour, time to confirm), the truth scores when the
recording holds simulation truth (``truth``: GOSPA, coverage, position RMSE) and timing.

An ASTERIX recording (CAT048 plots with CAT034 service messages; pcap of UDP or a raw
``.ast`` file, told apart from MCAP by its first bytes) is decoded with
:func:`skyfuse.services.asterix.read_asterix` (``--sites`` TOML, ``--date`` of the first
record). Plots without a flight level (primary-only, or Mode-S replies without altitude)
get ``--assumed-altitude`` (default: the radar site's height, i.e. its ground level;
± 3000 m; the live fusion service's default too). A file that is neither is an error
that says so (exit 1).

Online sensor registration (``--registration on|frozen|off``, ``--registration-reference``,
the ``[registration]`` table of ``--config``) estimates and corrects each radar's biases
as in the live service; the summary's ``registration`` holds the final estimates with
their σ, and ``plots_near_radar`` the plots kept by the near-radar projection.

Examples::

    skyfuse track --sample --out t.mcap
    skyfuse track r.mcap --tracker lmits --depth 3 --out t.mcap --json t.json
    skyfuse track r.mcap --config fusion.toml --frame-kind ned        # [tracker] table
    skyfuse track rec.pcap --sites sites.toml --date 2024-05-17 --tracker lmits --depth 3 \
        --out t.mcap --json t.json
    skyfuse track smr.ast mlat.ast adsb.ast --sites lebl.toml --date 2016-05-10  # merged

Several ASTERIX recordings of different sensors (a surface movement radar, a
multilateration system, ADS-B, radars) are read each on its own and merged in time order;
every sensor's position and kind come from the sites file (docs/concepts/sensors.md).
"""

from __future__ import annotations

import argparse
import datetime as dt
import logging
from pathlib import Path
from typing import Literal

from pydantic import Field
from skyfuse.schemas import FrameKind, PlotBatch, keys
from skyfuse.services.asterix.read_options import AsterixReadOptions
from skyfuse.services.fusion.registration_link import (
    add_registration_arguments,
    registration_config,
)
from skyfuse.services.runtime.config import (
    ConfigError,
    add_json_argument,
    add_model_arguments,
    build_config,
)
from skyfuse.services.runtime.progress import progress_bar

log = logging.getLogger(__name__)


class TrackCommandConfig(AsterixReadOptions):
    """Options of ``skyfuse track`` (the tracker itself is ``[tracker]`` / TrackerConfig)."""

    file: list[Path] = Field(
        [],
        description="Input recording: MCAP with sites and plot batches, or ASTERIX (.pcap of "
        "UDP, raw .ast: CAT048/CAT034 radars, CAT010/CAT020/CAT021 surface radar, "
        "multilateration, ADS-B); several ASTERIX files of different sensors are merged in "
        "time order; or --sample",
    )
    sample: bool = Field(False, description="Track the sample recording installed with skyfuse")
    out: Path = Field(Path("tracks.mcap"), description="Output MCAP with tracks and events")
    json_out: str | None = Field(
        None, description="Write the JSON summary to FILE (--json alone or -: to stdout)"
    )
    frame_kind: FrameKind = Field(
        FrameKind.STEREOGRAPHIC,
        description="System frame: stereographic or ned, centred on the mean of the radar sites "
        "known at the first plot batch (the live fusion service's rule)",
    )
    fusion_id: str = Field("main", description="Fusion id of the output topics")
    publish: Literal["confirmed", "all"] = Field(
        "confirmed", description="Tracks in each TrackBatch: confirmed or all"
    )
    progress: bool | None = Field(None, description="Show a progress bar (default: on a terminal)")
    coverage_window: float = Field(
        15.0, gt=0, description="A target counts as inside coverage this long after a plot, s"
    )
    sites: Path | None = Field(
        None, description="ASTERIX: sites TOML ([[radar]] sac, sic, lat, lon, alt, ...)"
    )
    date: dt.date | None = Field(
        None,
        description="ASTERIX: UTC date of the first record, YYYY-MM-DD (default: pcap capture "
        "time, else today)",
    )
    assumed_altitude: float | None = Field(
        None,
        ge=-1000,
        le=30000,
        description="Height assumed for plots without altitude/elevation, m, ± 3000 m (default: "
        "the radar site's height)",
    )


def _tracker_config_model():
    from skyfuse.fusion.tracker import TrackerConfig

    return TrackerConfig


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "track",
        help="run the tracker over a recording and write tracks/events (MCAP)",
        description=__doc__.split("\n\n")[0],
    )
    add_model_arguments(p, TrackCommandConfig, positional=("file",), skip=("json_out",))
    add_json_argument(p)
    p.add_argument("--config", type=Path, default=None, help="TOML file with a [tracker] table")
    group = p.add_argument_group("tracker")
    add_model_arguments(group, _tracker_config_model())
    add_registration_arguments(p)
    p.set_defaults(func=run)


def _counting(messages, advance):
    """``messages`` with ``advance(1)`` at each plot batch (the progress bar)."""
    for msg in messages:
        if isinstance(msg, PlotBatch):
            advance(1)
        yield msg


def _summary(cfg: TrackCommandConfig, tcfg, src, result, assumed) -> dict:
    from skyfuse.services.evaluation.observers import LABEL_WARMUP_S

    summary = {
        "file": ", ".join(map(str, cfg.file)),
        "out": str(cfg.out),
        "tracker": tcfg.tracker,
        "depth": tcfg.memory_depth,
        **result.summary(),
        "recording_rejected": dict(src.stats.rejected),
        "config": tcfg.model_dump(mode="json"),
    }
    ax = src.asterix
    if ax is not None:
        summary["asterix"] = {
            "radars": ax.radars,
            "scan_period_source": ax.scan_period_source,
            "assumed_altitude_m": assumed if assumed is not None else "site height",
            "label_warmup_s": LABEL_WARMUP_S,
            "counts": ax.stats,
            "messages": ax.messages[:20],
        }
    return summary


def run(args: argparse.Namespace) -> int:
    from skyfuse.services.evaluation import observers as obs
    from skyfuse.services.evaluation.inputs import InputError, open_input
    from skyfuse.services.evaluation.offline import OfflineConfig, run_offline
    from skyfuse.services.evaluation.report import write_summary
    from skyfuse.services.recording.mcap_io import RecordingWriter

    cfg = build_config(TrackCommandConfig, args)
    tcfg = build_config(
        _tracker_config_model(),
        args,
        toml_path=getattr(args, "config", None),
        section="tracker",
        env_prefix="SKYFUSE_TRACKER_",
    )
    keys.check_id(cfg.fusion_id, "fusion id")
    from skyfuse.services.recording.sample import chosen_recording

    try:
        first = chosen_recording(cfg.file[0] if cfg.file else None, cfg.sample)
    except (ValueError, FileNotFoundError) as e:
        raise ConfigError(f"file: {e}") from None
    cfg.file = [first, *cfg.file[1:]]
    try:
        src = open_input(
            cfg.file, sites_file=cfg.sites, date=cfg.date, sector_count=cfg.sector_count,
            report_window=cfg.report_window, adsb_sigma=cfg.adsb_sigma,
        )  # fmt: skip
    except InputError as e:
        if e.usage:
            raise ConfigError(str(e)) from None
        log.error("%s", e)
        return 1
    assumed = cfg.assumed_altitude
    ocfg = OfflineConfig(
        tracker=tcfg,
        frame_kind=cfg.frame_kind,
        fusion_id=cfg.fusion_id,
        publish=cfg.publish,
        assumed_altitude=assumed,
        registration=registration_config(args, toml_path=getattr(args, "config", None)),
    )
    warmup = obs.LABEL_WARMUP_S if src.asterix is not None else 0.0
    source = ", ".join(map(str, cfg.file))
    meta = {"command": "skyfuse track", "source": source, "tracker": tcfg.model_dump_json()}
    with (
        RecordingWriter(cfg.out, metadata=meta) as writer,
        progress_bar(f"track {first.name}", src.n_batches, enabled=cfg.progress) as advance,
    ):
        observers = [
            obs.TrackWriter(writer, cfg.fusion_id),
            obs.LabelObserver(warmup_s=warmup),
            obs.TruthObserver(obs.Coverage(cfg.coverage_window)),
            obs.Timing(),
        ]
        result = run_offline(_counting(src.messages(), advance), src.sites, ocfg, observers)
    if result.frame is None:
        log.error("%s: no plot batch of a radar with a site: nothing tracked", source)
        return 1
    write_summary(_summary(cfg, tcfg, src, result, assumed), cfg.json_out)
    return 0
