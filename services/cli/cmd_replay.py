"""``skyfuse replay FILE.mcap|--sample [--speed X | --fast]``: re-publish a recording's
radar sites and plot batches on Zenoh in their original timing (see
:mod:`skyfuse.services.sensors.replay`).

``--sample`` replays the recording installed with skyfuse (``regional-demo.mcap``). The
replay waits up to ``--wait-subscriber`` seconds for a subscriber of the plots (a fusion
service or a recorder on the same Zenoh network) and fails (exit 1) without one, as it
does for a file that is not MCAP or holds no plot batches: a replay nobody hears is an
error, not a success. ``--wait-subscriber 0`` publishes without checking.
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

from pydantic import BaseModel, Field
from skyfuse.schemas import keys
from skyfuse.services.cli.service_command import run_service
from skyfuse.services.recording.mcap_io import check_mcap
from skyfuse.services.runtime.config import ConfigError, add_model_arguments, build_config
from skyfuse.services.runtime.lifecycle import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK
from skyfuse.services.runtime.transport import (
    PLOT_CACHE,
    add_transport_arguments,
    declare_publisher,
    service_alive_key,
    transport_config,
    wait_for_tokens,
)
from skyfuse.services.sensors.replay import REPLAYED_KINDS, replay, replay_topics

log = logging.getLogger("skyfuse.replay")


class ReplayConfig(BaseModel):
    file: Path | None = Field(None, description="MCAP recording to replay (or --sample)")
    sample: bool = Field(False, description="Replay the sample recording installed with skyfuse")
    speed: float = Field(1.0, gt=0, le=10_000, description="Time scale: 2 = twice as fast")
    fast: bool = Field(False, description="Publish as fast as possible, ignoring timing")
    radars: list[str] | None = Field(None, description="Only these radar ids (default: all)")
    start_at: float | None = Field(
        None,
        gt=0,
        description="Unix time, s, at which the recording's start is due (default: when the "
        "replay starts): replays of one file given the same value stay in phase",
    )
    truth: bool = Field(False, description="Also publish the simulation truth")
    wait_for: list[str] = Field(
        default_factory=list,
        description="Service names (e.g. fusion,recorder) to wait for before starting",
    )
    wait_timeout: float = Field(10.0, gt=0, description="How long to wait for them, s")
    wait_subscriber: float = Field(
        5.0, ge=0, le=600, description="Wait this long for a plots subscriber, s (0: don't check)"
    )
    linger: float = Field(
        0.5, ge=0, le=30, description="Seconds to stay connected after the last message"
    )
    cache_batches: int = Field(
        PLOT_CACHE,
        ge=1,
        le=1_000_000,
        description="Plot batches each radar's publisher keeps for receivers that missed them",
    )


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "replay",
        help="re-publish a recording's sites and plots on Zenoh",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--config", default=None, help="TOML file ([replay] and [transport] tables)")
    add_model_arguments(p, ReplayConfig, positional=("file",))
    add_transport_arguments(p)
    p.set_defaults(func=run)


def recording_to_replay(cfg: ReplayConfig) -> Path:
    """The file to replay (``--sample`` or FILE), checked to be MCAP (``ConfigError``)."""
    from skyfuse.services.recording.sample import chosen_recording

    try:
        return check_mcap(chosen_recording(cfg.file, cfg.sample))
    except (ValueError, FileNotFoundError) as e:  # NotMcapError is a ValueError
        raise ConfigError(f"file: {e}") from None


def _topics_linear(path: Path, radars: set[str] | None) -> list[str]:
    """The site/plots topics of a recording without a summary (its writer was killed)."""
    from skyfuse.services.recording.mcap_io import iter_recording

    found = set()
    for rec in iter_recording(path, decode=False):
        try:
            info = keys.parse(rec.topic)
        except ValueError:
            continue
        if info.kind in REPLAYED_KINDS and (radars is None or info.owner in radars):
            found.add(rec.topic)
    return sorted(found)


def _wait_subscriber(session, topic: str, timeout: float, stop) -> bool:
    """Whether a subscriber of ``topic`` appears within ``timeout`` s (matching status)."""
    pub = declare_publisher(session, topic)
    try:
        end = time.monotonic() + timeout
        while not pub.matching_status.matching:
            if time.monotonic() >= end or stop.wait(0.05):
                return False
        return True
    finally:
        pub.undeclare()


def _replay(session, cfg: ReplayConfig, path: Path, topics: list[str], stop) -> int:
    keys_ = [service_alive_key(n) for n in cfg.wait_for]
    missing = wait_for_tokens(session, keys_, cfg.wait_timeout, stop)
    if missing:
        log.error("services not found after %.1f s: %s", cfg.wait_timeout, missing)
        return EXIT_FAILED
    plots = next(t for t in topics if t.endswith("/plots"))
    check = cfg.wait_subscriber > 0
    if check and not _wait_subscriber(session, plots, cfg.wait_subscriber, stop):
        log.error(
            "no subscriber for %s after %.1f s: start skyfuse fusion or record on the same "
            "Zenoh network (--connect/--listen), or give --wait-subscriber 0",
            keys.ALL_PLOTS,
            cfg.wait_subscriber,
        )
        return EXIT_FAILED
    radars = set(cfg.radars) if cfg.radars else None
    result = replay(
        session, path, speed=cfg.speed, fast=cfg.fast, radars=radars, truth=cfg.truth, stop=stop,
        start_at=cfg.start_at, cache=cfg.cache_batches,
    )  # fmt: skip
    if not stop.is_set():
        stop.wait(cfg.linger)
    log.info(
        "replayed %d messages (%d plot batches) of %s in %.2f s%s; read rejected %s",
        sum(result.published.values()),
        result.plot_batches,
        path.name,
        result.wall_s,
        " (interrupted)" if result.interrupted else "",
        dict(result.read.rejected) or "none",
    )
    if check and not result.subscribed:
        log.error("the plots subscriber went away: nobody received the replay")
        return EXIT_FAILED
    return EXIT_INTERRUPTED if result.interrupted else EXIT_OK


def run(args: argparse.Namespace) -> int:
    toml = getattr(args, "config", None)
    cfg = build_config(
        ReplayConfig, args, toml_path=toml, section="replay", env_prefix="SKYFUSE_REPLAY_"
    )
    path = recording_to_replay(cfg)
    radars = set(cfg.radars) if cfg.radars else None
    topics = replay_topics(path, REPLAYED_KINDS, radars) or _topics_linear(path, radars)
    if not any(t.endswith("/plots") for t in topics):
        log.error(
            "%s: no plot batches to replay%s",
            path,
            f" for radars {', '.join(sorted(radars))}" if radars else "",
        )
        return EXIT_FAILED
    tcfg = transport_config(args, toml_path=toml)
    return run_service(tcfg, lambda session, stop: _replay(session, cfg, path, topics, stop))
