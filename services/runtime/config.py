"""Configuration: pydantic models with working defaults, loadable from TOML, where every
command-line flag maps to a model field of the same name (``--scan-period`` ↔
``scan_period``). Precedence: defaults < TOML file < environment < command line.
"""

from __future__ import annotations

import argparse
import json
import os
import tomllib
import types
import typing
from enum import Enum
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError


class ConfigError(Exception):
    """A configuration value is invalid; the message names the field and the value."""


def _unwrap_optional(ann: Any) -> Any:
    origin = typing.get_origin(ann)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(ann) if a is not type(None)]
        if len(args) == 1:
            return args[0]
    return ann


def _split_list(text: str) -> list[str]:
    return [part.strip() for part in text.split(",") if part.strip()]


class _ExtendList(argparse.Action):
    """A list flag: ``--param a=1,b=2`` and ``--param a=1 --param b=2`` give the same
    list (a repeated flag adds to the list; it used to replace it silently)."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        setattr(namespace, self.dest, [*getattr(namespace, self.dest, []), *values])


def parse_key_values(items: list[str]) -> dict[str, Any]:
    """``["a=1", "b=x"]`` → ``{"a": 1, "b": "x"}``: values parsed as JSON where they are
    (numbers, booleans, lists), else kept as strings."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"{item!r} is not KEY=VALUE")
        try:
            out[key.strip()] = json.loads(value.strip())
        except json.JSONDecodeError:
            out[key.strip()] = value.strip()
    return out


def add_model_arguments(
    parser: argparse.ArgumentParser,
    model: type[BaseModel],
    *,
    positional: tuple[str, ...] = (),
    skip: tuple[str, ...] = (),
    short: dict[str, str] | None = None,
) -> None:
    """Add one flag per field of ``model``. Defaults are left to the model (argparse uses
    SUPPRESS) so that TOML values are not overridden by flags that were not given. A
    list field takes ``A,B,...`` and may be repeated (the values add up)."""
    short = short or {}
    for name, field in model.model_fields.items():
        if name in skip:
            continue
        ann = _unwrap_optional(field.annotation)
        if field.is_required():
            default = None
        elif field.default_factory is not None:
            default = field.default_factory()
        else:
            default = field.default
        if isinstance(default, Enum):
            default = default.value
        help_text = (field.description or "").rstrip(".")
        if default not in (None, "", [], ()):
            help_text += f" (default: {default})"
        if name in positional:
            nargs = None if field.is_required() else "?"
            if typing.get_origin(ann) is list:
                nargs = "+" if field.is_required() else "*"
            parser.add_argument(name, nargs=nargs, default=argparse.SUPPRESS, help=help_text)
            continue
        flags = ["--" + name.replace("_", "-")]
        if name in short:
            flags.insert(0, short[name])
        kwargs: dict[str, Any] = {"dest": name, "default": argparse.SUPPRESS, "help": help_text}
        if ann is bool:
            kwargs["action"] = argparse.BooleanOptionalAction
        elif typing.get_origin(ann) is list:
            kwargs["type"] = _split_list
            kwargs["action"] = _ExtendList
            kwargs["metavar"] = "A,B,..."
            kwargs["help"] = help_text + "; repeatable"
        elif isinstance(ann, type) and issubclass(ann, Enum):
            kwargs["choices"] = [e.value for e in ann]
        elif typing.get_origin(ann) is typing.Literal:
            kwargs["choices"] = list(typing.get_args(ann))
        parser.add_argument(*flags, **kwargs)


def load_toml(path: str | Path, section: str | None = None) -> dict[str, Any]:
    """Read a TOML file (optionally one table of it) as a dict."""
    p = Path(path)
    try:
        with p.open("rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise ConfigError(f"config file {str(p)!r} does not exist") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"config file {str(p)!r} is not valid TOML: {e}") from None
    if section is not None:
        data = data.get(section, {})
    return data


def _env_values(model: type[BaseModel], prefix: str) -> dict[str, str]:
    out = {}
    for name in model.model_fields:
        key = f"{prefix}{name.upper()}"
        if key in os.environ:
            out[name] = os.environ[key]
            ann = _unwrap_optional(model.model_fields[name].annotation)
            if typing.get_origin(ann) is list:
                out[name] = _split_list(os.environ[key])
    return out


def build_config(
    model: type[BaseModel],
    args: argparse.Namespace | None = None,
    *,
    toml_path: str | Path | None = None,
    section: str | None = None,
    env_prefix: str | None = None,
    overrides: dict[str, Any] | None = None,
):
    """Merge defaults < TOML < environment (``{env_prefix}{FIELD}``) < flags < overrides
    into a validated ``model`` instance; raise :class:`ConfigError` naming bad fields."""
    data: dict[str, Any] = {}
    if toml_path is not None:
        data.update(load_toml(toml_path, section))
    if env_prefix:
        data.update(_env_values(model, env_prefix))
    if args is not None:
        data.update({k: v for k, v in vars(args).items() if k in model.model_fields})
    if overrides:
        data.update(overrides)
    try:
        return model.model_validate(data)
    except ValidationError as e:
        raise ConfigError(format_validation_error(e)) from None


def format_validation_error(e: ValidationError) -> str:
    """One line per problem: ``field: message (got value)``."""
    lines = []
    for err in e.errors():
        loc = ".".join(str(p) for p in err["loc"]) or "(model)"
        value = err.get("input")
        shown = repr(value)
        if len(shown) > 60:
            shown = shown[:57] + "..."
        msg = err["msg"]
        if err["type"] == "value_error" or not err["loc"]:
            lines.append(f"{loc}: {msg}")
        else:
            lines.append(f"{loc}: {msg} (got {shown})")
    return "; ".join(lines)


def add_json_argument(
    parser: argparse.ArgumentParser,
    help_text: str = "Write the JSON summary to FILE; --json alone (or FILE -) prints it to stdout",
    default=argparse.SUPPRESS,
) -> None:
    """``--json [FILE]``: the one spelling of "JSON output" across the commands (``dest``
    ``json_out``; ``-`` when given without a file: standard output)."""
    parser.add_argument(
        "--json",
        dest="json_out",
        nargs="?",
        const="-",
        default=default,
        metavar="FILE",
        help=help_text,
    )
