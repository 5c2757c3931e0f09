"""``skyfuse router [--listen EP] [--tls-root-ca CA --tls-cert C --tls-key K] [--acl F]``:
a Zenoh router (the ``zenohd`` role) in a skyfuse process, for deployments where every
service is a Zenoh client of one router that checks certificates and enforces the access
policy (``skyfuse certs`` writes ``router.toml`` for it). Without ``--listen`` it listens
on 127.0.0.1:7447 only (``tls/`` when TLS is configured).

Runs until SIGINT/SIGTERM; exits 0, 1 if the session cannot be opened, 2 on a bad
configuration."""

from __future__ import annotations

import argparse
import logging

from skyfuse.services.runtime.lifecycle import EXIT_FAILED, EXIT_OK, StopFlag
from skyfuse.services.runtime.transport import (
    TransportError,
    add_transport_arguments,
    declare_liveliness,
    open_session,
    service_alive_key,
    transport_config,
)

log = logging.getLogger("skyfuse.router")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "router",
        help="run a Zenoh router (TLS, access control) for the skyfuse services",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--config", default=None, help="TOML file with a [transport] table")
    add_transport_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    tcfg = transport_config(args, toml_path=args.config).model_copy(update={"mode": "router"})
    stop = StopFlag().install()
    try:
        with open_session(tcfg) as session:
            token = declare_liveliness(session, service_alive_key("router"))
            log.info(
                "router %s listening on %s (TLS %s, access control %s)",
                session.info.zid(),
                tcfg.listen or "the default loopback endpoint",
                "on" if tcfg.tls else "off",
                tcfg.acl or "off",
            )
            stop.wait()
            token.undeclare()
    except TransportError as e:
        log.error("%s", e)
        return EXIT_FAILED
    return EXIT_OK
