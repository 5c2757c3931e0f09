"""``skyfuse replay FILE.mcap [--speed X | --fast]``: re-publish a recording's radar sites
and plot batches on Zenoh in their original timing (see :mod:`services.replay`)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from pydantic import BaseModel, Field
from skyfuse.services.cli.config import ConfigError, add_model_arguments, build_config
from skyfuse.services.runtime.lifecycle import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, StopFlag
from skyfuse.services.runtime.transport import (
    TransportError,
    add_transport_arguments,
    open_session,
    service_alive_key,
    transport_config,
    wait_for_tokens,
)
from skyfuse.services.sensors.replay import replay

log = logging.getLogger("skyfuse.replay")


class ReplayConfig(BaseModel):
    file: Path = Field(description="MCAP recording to replay")
    speed: float = Field(1.0, gt=0, le=10_000, description="Time scale: 2 = twice as fast")
    fast: bool = Field(False, description="Publish as fast as possible, ignoring timing")
    radars: list[str] | None = Field(None, description="Only these radar ids (default: all)")
    truth: bool = Field(False, description="Also publish the simulation truth")
    wait_for: list[str] = Field(
        default_factory=list,
        description="Service names (e.g. fusion,recorder) to wait for before starting",
    )
    wait_timeout: float = Field(10.0, gt=0, description="How long to wait for them, s")
    linger: float = Field(
        0.5, ge=0, le=30, description="Seconds to stay connected after the last message"
    )


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="re-publish a recording's sites and plots on Zenoh")
    add_model_arguments(p, ReplayConfig, positional=("file",))
    add_transport_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    cfg = build_config(ReplayConfig, args)
    if not cfg.file.is_file():
        raise ConfigError(f"file {str(cfg.file)!r} does not exist")
    tcfg = transport_config(args)
    stop = StopFlag().install()
    try:
        with open_session(tcfg) as session:
            missing = wait_for_tokens(
                session, [service_alive_key(n) for n in cfg.wait_for], cfg.wait_timeout, stop
            )
            if missing:
                log.error("services not found after %.1f s: %s", cfg.wait_timeout, missing)
                return EXIT_FAILED
            result = replay(
                session,
                cfg.file,
                speed=cfg.speed,
                fast=cfg.fast,
                radars=set(cfg.radars) if cfg.radars else None,
                truth=cfg.truth,
                stop=stop,
            )
            if not stop.is_set():
                stop.wait(cfg.linger)
    except TransportError as e:
        log.error("%s", e)
        return EXIT_FAILED
    log.info(
        "replayed %d messages (%d plot batches) in %.2f s%s; read rejected %s",
        sum(result.published.values()),
        result.plot_batches,
        result.wall_s,
        " (interrupted)" if result.interrupted else "",
        dict(result.read.rejected) or "none",
    )
    return EXIT_INTERRUPTED if result.interrupted else EXIT_OK
