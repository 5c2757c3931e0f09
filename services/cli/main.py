"""The ``skyfuse`` command line.

Each sub-command lives in its own module ``services/cli/cmd_<name>.py`` exposing
``register(subparsers)``; the module adds its parser with ``set_defaults(func=run)``
where ``run(args) -> int`` is the exit code. Exit codes: 0 success, 1 the job failed,
2 bad usage or configuration, 130 interrupted.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from pathlib import Path

from skyfuse.services.runtime.config import ConfigError


def command_modules() -> list[str]:
    """Every ``services/cli/cmd_*.py`` module, sorted: each registers one sub-command."""
    here = Path(__file__).parent
    return sorted(f"skyfuse.services.cli.{p.stem}" for p in here.glob("cmd_*.py"))


EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


def _requested_command(argv: list[str]) -> str | None:
    """The sub-command named on the command line, if it is one of ours (skipping the
    top-level ``--log-level L`` option)."""
    i = 0
    while i < len(argv):
        arg = argv[i]
        if arg == "--log-level":
            i += 2
            continue
        if arg.startswith("-"):
            return None
        module = f"skyfuse.services.cli.cmd_{arg}"
        return arg if module in command_modules() else None
    return None


def version() -> str:
    """The installed distribution's version (``pyproject.toml`` ``[project] version``); for
    a source tree used without installing, the version in its pyproject.toml."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as dist_version

    try:
        return dist_version("skyfuse")
    except PackageNotFoundError:
        import tomllib

        pyproject = Path(__file__).resolve().parents[2] / "pyproject.toml"
        try:
            return tomllib.loads(pyproject.read_text())["project"]["version"]
        except (OSError, KeyError, tomllib.TOMLDecodeError):
            return "unknown"


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The ``skyfuse`` parser with every sub-command, or only ``only`` (importing a
    command's module costs up to seconds: some import the tracker and SciPy)."""
    parser = argparse.ArgumentParser(
        prog="skyfuse",
        description="Distributed multi-radar fusion: simulate, track, record and replay.",
    )
    parser.add_argument("--version", action="version", version=f"skyfuse {version()}")
    parser.add_argument(
        "--log-level",
        default="INFO",
        choices=["DEBUG", "INFO", "WARNING", "ERROR"],
        help="Log level of messages on stderr (default: INFO)",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    names = [f"skyfuse.services.cli.cmd_{only}"] if only else command_modules()
    for name in names:
        importlib.import_module(name).register(sub)
    return parser


def setup_logging(level: str) -> None:
    logging.basicConfig(
        level=getattr(logging, level),
        format="%(asctime)s %(levelname)-7s %(name)s: %(message)s",
        stream=sys.stderr,
    )


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(only=_requested_command(argv))
    args = parser.parse_args(argv)
    setup_logging(args.log_level)
    try:
        code = args.func(args)
    except ConfigError as e:
        print(f"skyfuse {args.command}: configuration error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"skyfuse {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return int(code or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
