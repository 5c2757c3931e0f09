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

from skyfuse.services.cli.config import ConfigError, add_model_arguments, build_config
from skyfuse.services.runtime.lifecycle import EXIT_FAILED, EXIT_OK, StopFlag
from skyfuse.services.runtime.transport import (
    TransportError,
    add_transport_arguments,
    declare_liveliness,
    open_session,
    service_alive_key,
    transport_config,
    wait_for_tokens,
)
from skyfuse.services.sensors.config import SensorServiceConfig
from skyfuse.services.sensors.simulated import SimulatedRadar

log = logging.getLogger("skyfuse.sensor")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sensor",
        help="run a radar sensor (simulated, replayed or ASTERIX) publishing plots on Zenoh",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--config", default=None, help="TOML file ([sensor] and [transport] tables)")
    add_model_arguments(p, SensorServiceConfig)
    add_transport_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    cfg = build_config(
        SensorServiceConfig,
        args,
        toml_path=args.config,
        section="sensor",
        env_prefix="SKYFUSE_SENSOR_",
    )
    tcfg = transport_config(args, toml_path=args.config)
    modes = [m for m in ("replay", "asterix", "asterix_udp") if getattr(cfg, m) is not None]
    if len(modes) > 1:
        raise ConfigError(
            "choose one input: "
            + " and ".join("--" + m.replace("_", "-") for m in modes)
            + " were both given"
        )
    if cfg.mode in ("asterix", "asterix-udp"):
        return _run_asterix(cfg, tcfg)
    if cfg.radar is None:
        raise ConfigError("radar: --radar ID is required (except with --asterix/--asterix-udp)")
    if cfg.replay is not None and not cfg.replay.is_file():
        raise ConfigError(f"replay {str(cfg.replay)!r} does not exist")
    stop = StopFlag().install()
    try:
        with open_session(tcfg) as session:
            radar = ready = None
            if cfg.replay is None:
                radar = SimulatedRadar(session, cfg)  # declares the sensor's ready token
            else:
                ready = declare_liveliness(session, service_alive_key(f"sensor-{cfg.radar}"))
            try:
                missing = wait_for_tokens(
                    session, [service_alive_key(n) for n in cfg.wait_for], cfg.wait_timeout, stop
                )
                if missing:
                    log.error("services not found after %.1f s: %s", cfg.wait_timeout, missing)
                    return EXIT_FAILED
                if radar is None:
                    from skyfuse.services.sensors.replay import replay

                    res = replay(
                        session, cfg.replay, speed=cfg.speed, radars={cfg.radar}, stop=stop
                    )
                    log.info("radar %s: replayed %d plot batches", cfg.radar, res.plot_batches)
                    if res.plot_batches == 0:
                        log.warning("%s has no plot batches of radar %s", cfg.replay, cfg.radar)
                    return EXIT_OK
                log.info(
                    "radar %s (%s, %s) of scenario %s at speed %g",
                    cfg.radar,
                    radar.site.kind.value,
                    radar.site.name or "-",
                    cfg.scenario,
                    cfg.speed,
                )
                stats = radar.run(stop)
                if not stop.is_set():
                    stop.wait(cfg.linger)
                log.info(
                    "radar %s: published %d batches, %d plots%s (late by up to %.3f s)",
                    cfg.radar,
                    stats.published["plots"],
                    stats.plots,
                    " (stopped)" if stats.interrupted else "",
                    stats.late_s,
                )
            finally:
                if radar is not None:
                    radar.close()
                if ready is not None:
                    ready.undeclare()
    except TransportError as e:
        log.error("%s", e)
        return EXIT_FAILED
    return EXIT_OK


def _run_asterix(cfg, tcfg) -> int:
    """``--asterix FILE`` or ``--asterix-udp HOST:PORT``: every radar of the input."""
    from skyfuse.services.sensors.asterix_file import AsterixRecordingSensor
    from skyfuse.services.sensors.asterix_udp import AsterixUdpSensor

    if cfg.asterix is not None and not cfg.asterix.is_file():
        raise ConfigError(f"asterix {str(cfg.asterix)!r} does not exist")
    stop = StopFlag().install()
    try:
        with open_session(tcfg) as session:
            kind = AsterixRecordingSensor if cfg.asterix is not None else AsterixUdpSensor
            sensor = kind(session, cfg)
            try:
                missing = wait_for_tokens(
                    session, [service_alive_key(n) for n in cfg.wait_for], cfg.wait_timeout, stop
                )
                if missing:
                    log.error("services not found after %.1f s: %s", cfg.wait_timeout, missing)
                    return EXIT_FAILED
                stats = sensor.run(stop)
                if cfg.asterix is not None and not stop.is_set():
                    stop.wait(cfg.linger)
                by_radar = sensor.fleet.batches_by_radar
                log.info(
                    "published %d batches, %d plots of %d radars (%s)%s (late by up to %.3f s)",
                    stats.published["plots"],
                    stats.plots,
                    len(by_radar),
                    ", ".join(f"{r} {n}" for r, n in sorted(by_radar.items())),
                    " (stopped)" if stats.interrupted else "",
                    stats.late_s,
                )
            finally:
                sensor.close()
    except TransportError as e:
        log.error("%s", e)
        return EXIT_FAILED
    return EXIT_OK
