"""The parts every long-running service command shares (``skyfuse sensor``, ``fusion``,
``record``, ``cat062``, ``demo``): its parser (description from the module docstring,
``--config`` TOML, the model's flags, the transport flags), its configuration (defaults <
TOML table < ``SKYFUSE_<SECTION>_*`` environment < flags) and the run (SIGINT/SIGTERM
stop flag, one Zenoh session, exit code 1 when the network fails).
"""

from __future__ import annotations

import argparse
import logging
from collections.abc import Callable

from pydantic import BaseModel
from skyfuse.services.runtime.config import add_model_arguments, build_config
from skyfuse.services.runtime.lifecycle import EXIT_FAILED, StopFlag

log = logging.getLogger(__name__)


def add_service_parser(
    sub: argparse._SubParsersAction,
    name: str,
    help_text: str,
    doc: str | None,
    model: type[BaseModel] | None,
    *,
    tables: str | None,
    transport: bool = True,
    skip: tuple[str, ...] = (),
) -> argparse.ArgumentParser:
    """The sub-command parser: ``--config`` (a TOML file with ``tables``; none when
    ``tables`` is None), one flag per field of ``model`` (less ``skip``) and, with
    ``transport``, the Zenoh flags."""
    from skyfuse.services.runtime.transport import add_transport_arguments

    p = sub.add_parser(
        name,
        help=help_text,
        description=doc,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    if tables is not None:
        p.add_argument("--config", default=None, help=f"TOML file ({tables} tables)")
    if model is not None:
        add_model_arguments(p, model, skip=skip)
    if transport:
        add_transport_arguments(p)
    return p


def service_config(model: type[BaseModel], args: argparse.Namespace, section: str):
    """(the ``[section]`` model, the transport configuration) of a service command."""
    from skyfuse.services.runtime.transport import transport_config

    cfg = build_config(
        model,
        args,
        toml_path=args.config,
        section=section,
        env_prefix=f"SKYFUSE_{section.upper()}_",
    )
    return cfg, transport_config(args, toml_path=args.config)


def run_service(tcfg, body: Callable[[object, StopFlag], int | None], *, stop=None) -> int:
    """Install the stop flag, open the Zenoh session and run ``body(session, stop)``;
    its return value is the exit code (``None``: 0). A transport failure is logged and
    gives exit code 1. The objects of the start-up are frozen out of the garbage
    collector's full passes first (:mod:`~skyfuse.services.runtime.startup_heap`)."""
    from skyfuse.services.runtime.startup_heap import freeze_startup_heap
    from skyfuse.services.runtime.transport import TransportError, open_session

    stop = stop or StopFlag().install()
    try:
        with open_session(tcfg) as session:
            freeze_startup_heap()  # GC full passes skip what start-up built (stalls)
            return int(body(session, stop) or 0)
    except TransportError as e:
        log.error("%s", e)
        return EXIT_FAILED
