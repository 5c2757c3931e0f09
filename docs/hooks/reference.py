"""Generated reference pages of the documentation site: every CLI command and flag (from
the argparse parsers), every configuration field (from the pydantic models) and the wire
contract (the key table of ``schemas.keys`` and the fields of every ``schemas`` model).

The pages are built from the code at each docs build (``mkdocs build``, through the hook
``on_files`` below), never copied by hand, so they cannot drift from the code;
``tests/test_docs_reference.py`` checks that every parser action and every model field
appears in them.

This module lives beside the site (``docs/hooks/``, excluded from the pages) rather than in
the installed package: it is part of building the documentation, not of skyfuse.
"""

from __future__ import annotations

import argparse
import enum
import importlib
import inspect
import pkgutil
import re
import types
import typing
from dataclasses import dataclass, field

from pydantic import BaseModel
from pydantic_core import PydanticUndefined

#: The generated pages (path under docs/ → generator).
PAGES = {
    "reference/cli.md": "cli_markdown",
    "reference/configuration.md": "config_markdown",
    "reference/wire.md": "wire_markdown",
    "reports/result-tables.md": "result_tables_markdown",
}

#: Folders of result tables the benchmarks write beside the logs (not pages of the guide:
#: mkdocs.yml ``not_in_nav``); the generated index links every one of them.
RESULT_FOLDERS = ("crossing-4g", "reproduction")


@dataclass(frozen=True)
class Table:
    """A TOML table read by the commands: ``[name]`` ↔ ``model``, environment ``env``."""

    name: str
    model: str  # "module:Class"
    env: str | None
    commands: tuple[str, ...]
    note: str = ""
    #: field → the flag's dest when the flag is spelled differently from the field
    flag_dest: dict[str, str] = field(default_factory=dict)


#: Every ``--config`` TOML table. ``tests/test_docs_reference.py`` checks that every
#: table name the services read (``section=...`` in the code) is listed here.
TABLES = (
    Table(
        "tracker",
        "skyfuse.fusion.tracker:TrackerConfig",
        "SKYFUSE_TRACKER_",
        ("track", "eval", "fusion"),
        "The tracker: the same settings offline (`skyfuse track`, `skyfuse eval`) and live "
        "(`skyfuse fusion`).",
    ),
    Table(
        "registration",
        "skyfuse.fusion.registration:RegistrationConfig",
        "SKYFUSE_REGISTRATION_",
        ("track", "eval", "fusion"),
        "Online sensor registration (radar bias estimation); only `mode` and `reference` "
        "have flags.",
        {"mode": "registration", "reference": "registration_reference"},
    ),
    Table(
        "fusion",
        "skyfuse.services.fusion.service:FusionConfig",
        "SKYFUSE_FUSION_",
        ("fusion",),
        "The fusion service.",
    ),
    Table(
        "sensor",
        "skyfuse.services.sensors.config:SensorServiceConfig",
        "SKYFUSE_SENSOR_",
        ("sensor",),
        "A sensor process (simulated radar, MCAP replay, ASTERIX file or UDP feed).",
    ),
    Table(
        "record",
        "skyfuse.services.recording.recorder:RecorderConfig",
        "SKYFUSE_RECORD_",
        ("record",),
        "The MCAP recorder.",
    ),
    Table(
        "cat062",
        "skyfuse.services.cli.cmd_cat062:Cat062Config",
        "SKYFUSE_CAT062_",
        ("cat062",),
        "The CAT062 bridge (fused tracks out as ASTERIX).",
    ),
    Table(
        "tracks",
        "skyfuse.services.cli.cmd_tracks:TracksConfig",
        "SKYFUSE_TRACKS_",
        ("tracks",),
        "`skyfuse tracks`: the live table or JSON lines of the fused feed.",
    ),
    Table(
        "replay",
        "skyfuse.services.cli.cmd_replay:ReplayConfig",
        "SKYFUSE_REPLAY_",
        ("replay",),
        "`skyfuse replay`: re-publish recorded sites and plots.",
    ),
    Table(
        "simulate",
        "skyfuse.services.cli.cmd_simulate:SimulateConfig",
        None,
        ("simulate",),
        "`skyfuse simulate --config FILE.toml` (no environment variables).",
    ),
    Table(
        "transport",
        "skyfuse.services.runtime.transport:TransportConfig",
        "SKYFUSE_",
        ("fusion", "sensor", "record", "replay", "tracks", "cat062", "demo", "router"),
        "The Zenoh session of every networked command.",
    ),
)

#: Models that are not user configuration (built by code from the documented ones).
INTERNAL_MODELS = {
    "skyfuse.services.evaluation.offline.OfflineConfig": "assembled by `skyfuse track`/`eval` "
    "from the [tracker] and [registration] tables and the command's flags",
    "skyfuse.fusion.evaluation.experiment.Experiment": "assembled by `skyfuse eval` from its "
    "flags (the tracker evaluation options below)",
}

#: Units recognised at the end of a field's description (", m", ", s", ", rad ...").
_UNITS = (
    "m²/s⁴",
    "m²/s²",
    "rad/s",
    "m/s",
    "m²",
    "m³",
    "ns UTC",
    "ns",
    "ms",
    "s",
    "m",
    "rad",
    "deg",
    "degrees",
    "Hz",
    "bytes",
    "KiB",
    "MB",
    "ppm",
    "mrad",
    "plots/s",
    "FL",
    "g",
)
_UNIT_RE = re.compile(
    r",\s*(" + "|".join(re.escape(u) for u in _UNITS) + r")(?=$|[\s;:(.,)])", re.UNICODE
)


def _cell(text: object) -> str:
    """Text safe inside a Markdown table cell."""
    s = str(text).replace("\n", " ").replace("|", "\\|").strip()
    return s or "—"


def _code(text: object) -> str:
    s = str(text)
    return f"`{s}`" if s else "—"


def unit_of(description: str | None) -> str:
    """The unit named in a field description (``", m"``, ``", s"`` ...), or ``""``."""
    m = _UNIT_RE.search(description or "")
    return m.group(1) if m else ""


def _type_name(ann: object) -> str:
    origin = typing.get_origin(ann)
    if origin in (typing.Union, types.UnionType):
        parts = [_type_name(a) for a in typing.get_args(ann) if a is not type(None)]
        return " | ".join(parts) + (" | None" if type(None) in typing.get_args(ann) else "")
    if origin is typing.Literal:
        return " | ".join(repr(a).replace("'", '"') for a in typing.get_args(ann))
    if origin in (list, tuple, dict, set):
        args = ", ".join(_type_name(a) for a in typing.get_args(ann) if a is not Ellipsis)
        return f"{origin.__name__}[{args}]"
    if inspect.isclass(ann) and issubclass(ann, enum.Enum):
        return " | ".join(f'"{e.value}"' for e in ann)
    return getattr(ann, "__name__", str(ann))


def _default(f) -> str:
    if f.is_required():
        return "required"
    value = f.default_factory() if f.default_factory is not None else f.default
    if value is PydanticUndefined:
        return "required"
    if isinstance(value, enum.Enum):
        value = value.value
    if value is None:
        return "unset"
    if isinstance(value, str):
        return f'`"{value}"`'
    if isinstance(value, bool):
        return f"`{str(value).lower()}`"
    return f"`{value}`"


def _import(path: str) -> type[BaseModel]:
    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name)


# --------------------------------------------------------------------------------------
# the parsers
# --------------------------------------------------------------------------------------
def parsers() -> tuple[argparse.ArgumentParser, dict[str, argparse.ArgumentParser]]:
    """The ``skyfuse`` parser and each sub-command's parser, by name."""
    from skyfuse.services.cli.main import build_parser

    top = build_parser()
    sub = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction))
    return top, dict(sorted(sub.choices.items()))


def _help_of(top: argparse.ArgumentParser) -> dict[str, str]:
    sub = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction))
    return {c.dest: c.help or "" for c in sub._choices_actions}


def _value(action: argparse.Action) -> str:
    if action.nargs == 0:
        return "—"
    if action.choices:
        return " \\| ".join(f"`{c}`" for c in action.choices)
    if action.metavar:
        return _code(action.metavar)
    return _code(action.dest.upper())


def _flag_spelling(action: argparse.Action) -> str:
    if not action.option_strings:
        return f"`{action.dest}` (positional)"
    return ", ".join(f"`{s}`" for s in action.option_strings)


def _action_default(action: argparse.Action) -> str:
    d = action.default
    if d is argparse.SUPPRESS or d is None or (action.nargs == 0 and d is False):
        return ""
    return f" (default: {d})" if f"default: {d}" not in (action.help or "") else ""


def _command_markdown(name: str, parser: argparse.ArgumentParser, summary: str) -> list[str]:
    out = [f"## `skyfuse {name}` {{#{name}}}", "", _cell(summary) + ".", ""]
    usage = parser.format_usage().replace("usage: ", "", 1).strip()
    out += ["```text", usage, "```", ""]
    desc = (parser.description or "").strip().split("\n\n")[0]
    if desc:
        out += [_rst_inline(re.sub(r"\s*\n\s*", " ", desc)), ""]
    for group in parser._action_groups:
        actions = [a for a in group._group_actions if a.help is not argparse.SUPPRESS]
        if not actions:
            continue
        title = group.title or "options"
        out += [f"**{title}**", ""]
        if group.description:
            out += [_rst_inline(re.sub(r"\s*\n\s*", " ", group.description)), ""]
        out += ["| flag | value | meaning |", "|---|---|---|"]
        for a in actions:
            help_text = (a.help or "") % {"default": a.default, "prog": parser.prog}
            help_text = help_text + _action_default(a)
            out.append(f"| {_flag_spelling(a)} | {_value(a)} | {_cell(help_text)} |")
        out.append("")
    return out


def cli_markdown() -> str:
    """The CLI reference page: every command, every flag, from the parsers."""
    top, commands = parsers()
    helps = _help_of(top)
    lines = [
        "# Command line",
        "",
        "Generated from the `skyfuse` argparse parsers at each documentation build. Every "
        "command also takes `--help`. Flags map one-to-one onto configuration fields "
        "(`--scan-period` ↔ `scan_period`, see [Configuration](configuration.md)); "
        "precedence: defaults < TOML file < environment < flags. Exit codes: 0 done, "
        "1 the job failed, 2 bad usage or configuration, 3 a service overran its shutdown "
        "deadline, 130 interrupted.",
        "",
        "```text",
        top.format_usage().replace("usage: ", "", 1).strip(),
        "```",
        "",
        "| command | what it does |",
        "|---|---|",
    ]
    lines += [f"| [`{n}`](#{n}) | {_cell(helps.get(n, ''))} |" for n in commands]
    lines += ["", "Options of `skyfuse` itself:", "", "| flag | value | meaning |", "|---|---|---|"]
    for a in top._actions:
        if a.option_strings and a.help is not argparse.SUPPRESS:
            lines.append(f"| {_flag_spelling(a)} | {_value(a)} | {_cell(a.help)} |")
    lines.append("")
    for name, p in commands.items():
        lines += _command_markdown(name, p, helps.get(name, ""))
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------
# the configuration models
# --------------------------------------------------------------------------------------
def configuration_models() -> dict[str, type[BaseModel]]:
    """Every pydantic model of ``skyfuse.fusion`` and ``skyfuse.services`` (wire models of
    ``skyfuse.schemas`` excluded), by ``module.Class``: found by importing every module,
    so a new configuration model cannot be left out of the reference."""
    found: dict[str, type[BaseModel]] = {}
    for root in ("skyfuse.fusion", "skyfuse.services"):
        pkg = importlib.import_module(root)
        for info in pkgutil.walk_packages(pkg.__path__, root + "."):
            if info.name.endswith("__main__"):
                continue
            mod = importlib.import_module(info.name)
            for obj in vars(mod).values():
                if (
                    inspect.isclass(obj)
                    and issubclass(obj, BaseModel)
                    and obj.__module__ == mod.__name__
                ):
                    found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return dict(sorted(found.items()))


def _flags_for(model: type[BaseModel], commands: dict[str, argparse.ArgumentParser]):
    """field name → [(command, '--flag')] of the flags generated from this model's field
    (same dest, help text starting with the field's description)."""
    out: dict[str, list[tuple[str, str]]] = {}
    for fname, f in model.model_fields.items():
        desc = (f.description or "").rstrip(".")
        for cname, p in commands.items():
            for a in p._actions:
                if a.dest == fname and (a.help or "").startswith(desc):
                    spelled = a.option_strings[-1] if a.option_strings else fname
                    out.setdefault(fname, []).append((cname, spelled))
    return out


def _dest_flags(dest: str, names: tuple[str, ...], commands) -> list[tuple[str, str]]:
    out = []
    for cname in names:
        for a in commands[cname]._actions if cname in commands else ():
            if a.dest == dest and a.option_strings:
                out.append((cname, a.option_strings[-1]))
    return out


def _flag_cell(flags: list[tuple[str, str]], every: tuple[str, ...] = ()) -> str:
    """``--flag`` and the commands that take it (left out when that is all of ``every``,
    the commands of the table, listed in its heading)."""
    if not flags:
        return "—"
    by_flag: dict[str, list[str]] = {}
    for cname, flag in flags:
        by_flag.setdefault(flag, []).append(cname)
    cells = []
    for flag, cs in by_flag.items():
        if every and set(cs) == set(every):
            cells.append(f"`{flag}`")
        else:
            cells.append(f"`{flag}` ({', '.join(f'[{c}](cli.md#{c})' for c in cs)})")
    return "; ".join(cells)


def _model_table(
    model: type[BaseModel], key_prefix: str | None, flags_of, every: tuple[str, ...] = ()
) -> list[str]:
    head = (
        "| TOML key | type | default | unit | meaning | flag |"
        if key_prefix is not None
        else ("| field | type | default | unit | meaning | flag |")
    )
    out = [head, "|---|---|---|---|---|---|"]
    nested = []
    for name, f in model.model_fields.items():
        ann = f.annotation
        args = typing.get_args(ann)
        if typing.get_origin(ann) is list and args and inspect.isclass(args[0]):
            if issubclass(args[0], BaseModel):
                nested.append((name, args[0]))
        key = f"`{name}`"
        out.append(
            f"| {key} | {_cell(_type_name(ann))} | {_default(f)} | {_cell(unit_of(f.description))}"
            f" | {_cell(f.description or '')} | {_flag_cell(flags_of(name), every)} |"
        )
    for name, sub in nested:
        table = f"[[{key_prefix}.{name}]]" if key_prefix else name
        out += [
            "",
            f"Each `{table}` entry ({sub.__name__}, from `skyfuse.schemas`):",
            "",
            "| key | type | default | unit | meaning |",
            "|---|---|---|---|---|",
        ]
        for n, f in sub.model_fields.items():
            out.append(
                f"| `{n}` | {_cell(_type_name(f.annotation))} | {_default(f)} | "
                f"{_cell(unit_of(f.description))} | {_cell(f.description or '')} |"
            )
    return out


def _sites_file_markdown() -> list[str]:
    from skyfuse.schemas import RadarSite
    from skyfuse.services.asterix.sites import REQUIRED_KEYS, SITE_KEYS

    rows = ["| key | required | unit | meaning |", "|---|---|---|---|"]
    rows.append("| `sac`, `sic` | yes | — | System Area Code and System Identification Code |")
    for k in SITE_KEYS:
        f = RadarSite.model_fields[k]
        req = "yes" if k in REQUIRED_KEYS else "no"
        rows.append(f"| `{k}` | {req} | {_cell(unit_of(f.description))} | {_cell(f.description)} |")
    return [
        "## ASTERIX sites file `[[radar]]` {#sites-file}",
        "",
        "`--sites FILE.toml` of `skyfuse track`, `eval` and `sensor`: one `[[radar]]` table per "
        "radar; its id is `SAC-SIC` (e.g. `20-129`). Any `RadarSite` field may be given "
        "besides the required ones ([wire reference](wire.md#radarsite)).",
        "",
        *rows,
        "",
    ]


def config_markdown() -> str:
    """The configuration reference: every TOML table and every configuration model."""
    _, commands = parsers()
    lines = [
        "# Configuration",
        "",
        "Generated from the pydantic models at each documentation build. Every field has a "
        "working default. A command that takes `--config FILE.toml` reads the tables named "
        "below from it; the services also read environment variables "
        "`<PREFIX><FIELD>` (upper case, e.g. `SKYFUSE_TRACKER_DEPTH=5`); a flag named in the "
        "last column overrides both. Precedence: defaults < TOML < environment < flags. "
        "The unit column is taken from the field's description.",
        "",
        "```toml",
        "# fusion.toml: skyfuse fusion --config fusion.toml",
        "[fusion]",
        'fusion_id = "main"',
        "reorder_wait = 0.5",
        "",
        "[tracker]",
        'tracker = "lmits"',
        "depth = 3",
        "",
        "[registration]",
        'mode = "on"',
        "",
        "[transport]",
        'connect = ["tcp/127.0.0.1:7447"]',
        "```",
        "",
        "## TOML tables",
        "",
        "| table | model | environment | read by |",
        "|---|---|---|---|",
    ]
    documented = set()
    for t in TABLES:
        model = _import(t.model)
        documented.add(f"{model.__module__}.{model.__qualname__}")
        cmds = ", ".join(f"[{c}](cli.md#{c})" for c in t.commands)
        env = f"`{t.env}<FIELD>`" if t.env else "—"
        lines.append(f"| [`[{t.name}]`](#{t.name}) | `{model.__name__}` | {env} | {cmds} |")
    lines.append("")
    for t in TABLES:
        model = _import(t.model)
        model_flags = _flags_for(model, {c: commands[c] for c in t.commands if c in commands})

        def flags_of(name, t=t, model_flags=model_flags):
            if name in t.flag_dest:
                return _dest_flags(t.flag_dest[name], t.commands, commands)
            return model_flags.get(name, [])

        lines += [
            f"### `[{t.name}]` {{#{t.name}}}",
            "",
            f"{t.note} Model: `{model.__module__}.{model.__name__}`.",
            "",
        ]
        cmds = ", ".join(f"[{c}](cli.md#{c})" for c in t.commands)
        lines += [f"Flags: of the commands {cmds} unless the row names others.", ""]
        lines += _model_table(model, t.name, flags_of, t.commands)
        lines.append("")
    lines += _sites_file_markdown()
    lines += [
        "## Command options",
        "",
        "The options of the other commands (flags only, no TOML table), one model each.",
        "",
    ]
    for path, model in configuration_models().items():
        if path in documented:
            continue
        if path in INTERNAL_MODELS:
            continue
        anchor = model.__name__.lower()
        flags = _flags_for(model, commands)
        doc = re.sub(r"\s*\n\s*", " ", (model.__doc__ or "").strip().split("\n\n")[0])
        lines += [f"### `{model.__name__}` {{#{anchor}}}", "", f"{doc} Model: `{path}`.", ""]
        lines += _model_table(model, None, lambda n, flags=flags: flags.get(n, []))
        lines.append("")
    lines += ["## Internal models", ""]
    for path, why in INTERNAL_MODELS.items():
        lines.append(f"* `{path}`: {why}.")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------
# the wire contract
# --------------------------------------------------------------------------------------
def key_table() -> list[tuple[str, str, str]]:
    """(key expression, payload, direction) rows of the table in ``schemas.keys``'s
    docstring (a reStructuredText simple table)."""
    from skyfuse.schemas import keys

    rows = []
    lines = (keys.__doc__ or "").splitlines()
    rules = [i for i, line in enumerate(lines) if re.fullmatch(r"=+(\s+=+)+", line.strip())]
    if len(rules) < 3:
        raise ValueError("schemas.keys docstring: no key table found")
    spans = [(m.start(), m.end()) for m in re.finditer(r"=+", lines[rules[0]])]
    for line in lines[rules[1] + 1 : rules[2]]:
        if not line.strip():
            continue
        cols = []
        for j, (a, _) in enumerate(spans):
            b = spans[j + 1][0] if j + 1 < len(spans) else len(line)
            cols.append(line[a:b].strip())
        rows.append(tuple(cols))
    return rows


def _rst_inline(text: str, link: frozenset[str] = frozenset()) -> str:
    """reStructuredText inline markup → Markdown (``:class:`X``` → a link to the anchor
    ``#x`` of this page when X is in ``link``, else code)."""

    def role(m: re.Match) -> str:
        name = m.group(2).split(".")[-1]
        return f"[`{name}`](#{name.lower()})" if name in link else f"`{name}`"

    text = re.sub(r":(\w+):`~?([^`]+)`", role, text)
    return text.replace("``", "`")


def wire_models() -> dict[str, type[BaseModel]]:
    """Every pydantic model exported by ``skyfuse.schemas``, by name."""
    import skyfuse.schemas as schemas

    out = {}
    for name in schemas.__all__:
        obj = getattr(schemas, name)
        if inspect.isclass(obj) and issubclass(obj, BaseModel):
            out[name] = obj
    return out


def wire_markdown() -> str:
    """The wire reference: the key table and the fields of every message model."""
    import skyfuse.schemas as schemas

    lines = [
        "# Wire contract: keys and messages",
        "",
        "Generated from `skyfuse.schemas` at each documentation build. Payloads are compact "
        "JSON of these pydantic models; the same key names are the MCAP topics. "
        "`skyfuse schemas --out DIR` writes them as JSON Schema. How a subscriber rebuilds "
        "the track picture from the feed: [the feed contract](../concepts/feed.md).",
        "",
        "## Key space {#keys}",
        "",
        "| key expression | payload | direction |",
        "|---|---|---|",
    ]
    names = frozenset(wire_models())
    for key, payload, direction in key_table():
        lines.append(f"| {_rst_inline(key)} | {_rst_inline(payload, names)} | {_cell(direction)} |")
    lines += ["", "Key kinds and their payload model (`schemas.MODELS`):", ""]
    lines += [
        f"* `{k}`: [`{m.__name__}`](#{m.__name__.lower()})" for k, m in schemas.MODELS.items()
    ]
    lines += ["", f"Schema version: `{schemas.SCHEMA_VERSION}`.", ""]
    for name, model in wire_models().items():
        doc = (model.__doc__ or "").strip()
        lines += [f"## `{name}` {{#{name.lower()}}}", ""]
        if doc:
            lines += [_rst_inline(re.sub(r"\s*\n\s*", " ", doc.split("\n\n")[0]), names), ""]
        lines += ["| field | type | default | unit | meaning |", "|---|---|---|---|---|"]
        for fname, f in model.model_fields.items():
            lines.append(
                f"| `{fname}` | {_cell(_type_name(f.annotation))} | {_default(f)} | "
                f"{_cell(unit_of(f.description))} | {_cell(f.description or '')} |"
            )
        lines.append("")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------
# the index of generated result tables
# --------------------------------------------------------------------------------------
def result_tables_markdown() -> str:
    """An index of every Markdown table the benchmarks wrote under ``docs/crossing-4g/``
    and ``docs/reproduction/``, so that each is reachable from the navigation."""
    from pathlib import Path

    docs = Path(__file__).resolve().parents[1]
    lines = [
        "# Result tables",
        "",
        "The tables the evaluation scripts wrote beside their JSON and figures, referred to by "
        "the [reproduction log](reproduction-log.md) and the [crossing-4g log](crossing-4g-log.md) "
        "(historical, like them). The current results: [Reproduction](../reproduction.md).",
        "",
    ]
    for folder in RESULT_FOLDERS:
        lines += [f"## `{folder}/`", ""]
        for path in sorted((docs / folder).rglob("*.md")):
            rel = path.relative_to(docs).as_posix()
            lines.append(f"* [`{path.relative_to(docs / folder).as_posix()}`](../{rel})")
        lines.append("")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------
# the MkDocs hook
# --------------------------------------------------------------------------------------
def on_files(files, config):
    """Add the generated reference pages to the site."""
    from mkdocs.structure.files import File

    for path, generator in PAGES.items():
        files.append(File.generated(config, path, content=globals()[generator]()))
    return files


def on_startup(command, dirty):
    """The Python API pages (mkdocstrings) read the sources statically: the repository's
    folders ``fusion/``, ``schemas/`` and ``services/`` install as ``skyfuse.fusion`` ...
    (setuptools ``package-dir``), so ``build/api-src/skyfuse/`` gets one link per folder
    and the handler searches ``build/api-src`` (mkdocs.yml ``paths``). At start-up:
    before any plugin reads its configuration."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    pkg = root / "build" / "api-src" / "skyfuse"
    pkg.mkdir(parents=True, exist_ok=True)
    for name in ("fusion", "schemas", "services"):
        link = pkg / name
        if not link.is_symlink():
            link.symlink_to(root / name, target_is_directory=True)
