"""``skyfuse sensor --radar ID --scenario NAME [--speed X] [--connect EP | --listen EP]``:
one simulated radar publishing its site and sector plot batches on Zenoh in (scaled) real
time; ``--replay FILE.mcap`` publishes that radar's recorded batches instead.

Real radar data (ASTERIX CAT048 plots with CAT034 service messages), every radar of the
input served by this one process (``--radar SAC-SIC`` keeps one):

    skyfuse sensor --asterix rec.pcap --sites sites.toml [--date 2024-05-17] [--speed 4]
    skyfuse sensor --asterix-udp 127.0.0.1:30048 --sites sites.toml

``--asterix`` decodes the file (pcap of UDP, or raw .ast) and publishes the sites (message,
queryable, liveliness token per radar) and the sector batches paced by their times;
``--asterix-udp`` listens for a live feed and publishes each sector as it completes.

Exits 0 at the end of the scenario or on SIGINT/SIGTERM, 1 if the network fails, 2 on a
bad configuration (e.g. a radar id the scenario does not have)."""

from __future__ import annotations

import argparse
import logging

from skyfuse.services.cli.service_command import add_service_parser, run_service, service_config
from skyfuse.services.runtime.config import ConfigError
from skyfuse.services.runtime.lifecycle import EXIT_FAILED, EXIT_OK
from skyfuse.services.runtime.transport import (
    declare_liveliness,
    service_alive_key,
    wait_for_tokens,
)
from skyfuse.services.sensors.config import SensorServiceConfig, start_time_ns

log = logging.getLogger("skyfuse.sensor")


def register(sub: argparse._SubParsersAction) -> None:
    p = add_service_parser(
        sub, "sensor",
        "run a radar sensor (simulated, replayed or ASTERIX) publishing plots on Zenoh",
        __doc__, SensorServiceConfig, tables="[sensor] and [transport]",
    )  # fmt: skip
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    cfg, tcfg = service_config(SensorServiceConfig, args, "sensor")
    modes = [m for m in ("replay", "asterix", "asterix_udp") if getattr(cfg, m) is not None]
    if len(modes) > 1:
        raise ConfigError(
            "choose one input: "
            + " and ".join("--" + m.replace("_", "-") for m in modes)
            + " were both given"
        )
    if cfg.mode in ("asterix", "asterix-udp"):
        if cfg.asterix is not None and not cfg.asterix.is_file():
            raise ConfigError(f"asterix {str(cfg.asterix)!r} does not exist")
        return run_service(tcfg, lambda session, stop: _asterix(session, cfg, stop))
    if cfg.radar is None:
        raise ConfigError("radar: --radar ID is required (except with --asterix/--asterix-udp)")
    if cfg.replay is not None:
        if not cfg.replay.is_file():
            raise ConfigError(f"replay {str(cfg.replay)!r} does not exist")
        return run_service(tcfg, lambda session, stop: _replay(session, cfg, stop))
    return run_service(tcfg, lambda session, stop: _simulated(session, cfg, stop))


def _waited(session, cfg: SensorServiceConfig, stop) -> bool:
    """Wait for the ``--wait-for`` services; False (logged) if some did not come."""
    keys_ = [service_alive_key(n) for n in cfg.wait_for]
    missing = wait_for_tokens(session, keys_, cfg.wait_timeout, stop)
    if missing:
        log.error("services not found after %.1f s: %s", cfg.wait_timeout, missing)
    return not missing


def _replay(session, cfg: SensorServiceConfig, stop) -> int:
    """``--replay FILE.mcap --radar ID``: that radar's recorded batches."""
    from skyfuse.services.sensors.replay import replay

    ready = declare_liveliness(session, service_alive_key(f"sensor-{cfg.radar}"))
    try:
        if not _waited(session, cfg, stop):
            return EXIT_FAILED
        start = start_time_ns(cfg) / 1e9  # --start-at / --align, else now
        res = replay(
            session, cfg.replay, speed=cfg.speed, radars={cfg.radar}, stop=stop, start_at=start,
            cache=cfg.cache_batches,
        )  # fmt: skip
    finally:
        ready.undeclare()
    log.info("radar %s: replayed %d plot batches", cfg.radar, res.plot_batches)
    if res.plot_batches == 0:
        log.error("%s has no plot batches of radar %s", cfg.replay, cfg.radar)
        return EXIT_FAILED
    return EXIT_OK


def _simulated(session, cfg: SensorServiceConfig, stop) -> int:
    """One radar of a scenario (``--radar ID --scenario NAME``)."""
    from skyfuse.services.sensors.simulated import SimulatedRadar

    radar = SimulatedRadar(session, cfg)  # declares the sensor's ready token
    try:
        if not _waited(session, cfg, stop):
            return EXIT_FAILED
        log.info(
            "radar %s (%s, %s) of scenario %s at speed %g",
            cfg.radar, radar.site.kind.value, radar.site.name or "-", cfg.scenario, cfg.speed,
        )  # fmt: skip
        stats = radar.run(stop)
        if not stop.is_set():
            stop.wait(cfg.linger)
        log.info(
            "radar %s: published %d batches, %d plots%s (late by up to %.3f s)",
            cfg.radar, stats.published["plots"], stats.plots,
            " (stopped)" if stats.interrupted else "", stats.late_s,
        )  # fmt: skip
    finally:
        radar.close()
    return EXIT_OK


def _asterix(session, cfg: SensorServiceConfig, stop) -> int:
    """``--asterix FILE`` or ``--asterix-udp HOST:PORT``: every radar of the input."""
    from skyfuse.services.sensors.asterix_file import AsterixRecordingSensor
    from skyfuse.services.sensors.asterix_udp import AsterixUdpSensor

    kind = AsterixRecordingSensor if cfg.asterix is not None else AsterixUdpSensor
    sensor = kind(session, cfg)
    try:
        if not _waited(session, cfg, stop):
            return EXIT_FAILED
        stats = sensor.run(stop)
        if cfg.asterix is not None and not stop.is_set():
            stop.wait(cfg.linger)
        by_radar = sensor.fleet.batches_by_radar
        log.info(
            "published %d batches, %d plots of %d radars (%s)%s (late by up to %.3f s)",
            stats.published["plots"], stats.plots, len(by_radar),
            ", ".join(f"{r} {n}" for r, n in sorted(by_radar.items())),
            " (stopped)" if stats.interrupted else "", stats.late_s,
        )  # fmt: skip
    finally:
        sensor.close()
    return EXIT_OK
