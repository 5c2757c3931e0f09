"""``skyfuse fusion [--config fusion.toml] [--listen EP] [--connect EP]``: the fusion
service. Subscribes to every radar's plots and sites, orders batches across radars,
runs the configured tracker and publishes on ``skyfuse/@v1/fusion/{id}/…``:
``tracks`` (the track feed: a delta TrackBatch after each cycle — or group of cycles
when several batches are ready at once — and the full picture every ``--full-interval``
s), ``events`` (TrackEvents), ``status`` (periodic Status with the backlog; also a
queryable answering the last one), ``registration`` (the radar bias estimates,
RegistrationStatus, with each Status) and the queryable ``snapshot`` (the full picture now;
see ``schemas.tracks`` for the contract). Payloads are JSON with the Zenoh encoding
``application/json;skyfuse.{Model}/{schema version}``.

TOML: ``[fusion]`` (this service, incl. ``[[fusion.sites]]``), ``[tracker]`` (the
tracker, see ``fusion.tracker.TrackerConfig``), ``[registration]`` (the online sensor
registration, ``fusion.registration.RegistrationConfig``), ``[transport]``. Environment:
``SKYFUSE_FUSION_*``, ``SKYFUSE_TRACKER_*``, ``SKYFUSE_REGISTRATION_*``, ``SKYFUSE_*``
(transport).

Exits 0 on SIGINT/SIGTERM (after applying what is buffered), 1 if the network fails,
2 on a bad configuration."""

from __future__ import annotations

import argparse
import logging

from skyfuse.services.cli.service_command import add_service_parser, run_service, service_config
from skyfuse.services.fusion.registration_link import (
    add_registration_arguments,
    registration_config,
)
from skyfuse.services.fusion.server import make_pipeline_factory, serve
from skyfuse.services.fusion.service import FusionConfig, FusionCore
from skyfuse.services.fusion.state_store import Persistence
from skyfuse.services.runtime.config import ConfigError, add_model_arguments, build_config
from skyfuse.services.runtime.transport import add_transport_arguments

log = logging.getLogger("skyfuse.fusion")


def _tracker_config_model():
    from skyfuse.fusion.tracker import TrackerConfig

    return TrackerConfig


def register(sub: argparse._SubParsersAction) -> None:
    p = add_service_parser(
        sub, "fusion", "run the fusion service (plots in, fused tracks out)", __doc__,
        FusionConfig, tables="[fusion], [tracker] and [transport]", transport=False,
        skip=("sites",),
    )  # fmt: skip
    group = p.add_argument_group(
        "tracker",
        "The tracker (the same flags as skyfuse track and eval); also the [tracker] TOML "
        "table and SKYFUSE_TRACKER_<FIELD>",
    )
    add_model_arguments(group, _tracker_config_model())
    add_registration_arguments(p)
    cat = p.add_argument_group("ASTERIX CAT062 output (see skyfuse cat062)")
    cat.add_argument(
        "--cat062-udp",
        default=None,
        metavar="HOST:PORT",
        help="Also send every TrackBatch as CAT062 UDP datagrams to HOST:PORT",
    )
    cat.add_argument("--cat062-sac", type=int, default=0, help="I062/010 SAC (default: 0)")
    cat.add_argument("--cat062-sic", type=int, default=1, help="I062/010 SIC (default: 1)")
    add_transport_arguments(p)  # last: after the CAT062 group, as in the other commands
    p.set_defaults(func=run)


def tracker_config(args: argparse.Namespace):
    """The TrackerConfig: defaults < TOML [tracker] < SKYFUSE_TRACKER_* < flags."""
    return build_config(
        _tracker_config_model(),
        args,
        toml_path=getattr(args, "config", None),
        section="tracker",
        env_prefix="SKYFUSE_TRACKER_",
    )


def run(args: argparse.Namespace) -> int:
    cfg, tcfg = service_config(FusionConfig, args, "fusion")
    tracker_cfg = tracker_config(args)
    reg_cfg = registration_config(args, toml_path=getattr(args, "config", None))
    core = FusionCore(
        cfg,
        make_pipeline_factory(
            tracker_cfg, cfg.fusion_id, assumed_altitude=cfg.assumed_altitude, registration=reg_cfg
        ),
    )
    try:
        persist = Persistence.from_config(core)
    except OSError as e:  # PermissionError included: an unsafe or unusable state dir
        raise ConfigError(f"state_dir: {e}") from None
    cat062 = None
    if getattr(args, "cat062_udp", None):
        from skyfuse.services.cli.cmd_cat062 import Cat062UdpSender

        try:
            cat062 = Cat062UdpSender(args.cat062_udp, sac=args.cat062_sac, sic=args.cat062_sic)
        except ValueError as e:
            raise ConfigError(str(e)) from None
    try:
        return run_service(
            tcfg, lambda session, stop: serve(session, core, stop, cat062=cat062, persist=persist)
        )
    finally:
        if cat062 is not None:
            log.info("cat062 output: %s", dict(cat062.stats))
            cat062.close()
