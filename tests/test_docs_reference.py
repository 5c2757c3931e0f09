"""The generated reference pages of the documentation site (docs/hooks/reference.py) hold
every CLI command and flag, every configuration field with its TOML key, and every wire
model field and key: generated here from the same code the site is built from, then
checked item by item against the parsers and models themselves."""

from __future__ import annotations

import argparse
import ast
import importlib.util
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _load(name: str):
    path = ROOT / "docs" / "hooks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"docs_hooks_{name}", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def ref():
    return _load("reference")


def _sections(text: str) -> dict[str, str]:
    """Page text by ``## `skyfuse NAME` {#NAME}`` section."""
    parts = re.split(r"^## `skyfuse (\S+)` \{#\S+\}$", text, flags=re.M)
    return dict(zip(parts[1::2], parts[2::2], strict=True))


def test_every_command_and_flag_is_in_the_cli_reference(ref):
    top, commands = ref.parsers()
    page = ref.cli_markdown()
    sections = _sections(page)
    assert set(sections) == set(commands)
    for a in top._actions:
        for flag in a.option_strings:
            assert f"`{flag}`" in page, flag
    missing = []
    for name, parser in commands.items():
        for a in parser._actions:
            if a.help is argparse.SUPPRESS:
                continue
            spellings = a.option_strings or [a.dest]
            for s in spellings:
                if f"`{s}`" not in sections[name]:
                    missing.append(f"skyfuse {name} {s}")
            if a.help and a.option_strings:
                first_words = (a.help % {"default": a.default, "prog": parser.prog})[:30]
                if ref._cell(first_words) not in sections[name]:
                    missing.append(f"skyfuse {name} {a.option_strings[-1]}: help text")
    assert missing == []


def test_every_configuration_field_is_in_the_configuration_reference(ref):
    page = ref.config_markdown()
    missing = []
    for t in ref.TABLES:
        model = ref._import(t.model)
        section = page.split(f"### `[{t.name}]`", 1)[1].split("\n### ", 1)[0]
        for name, field in model.model_fields.items():
            row = next((r for r in section.splitlines() if r.startswith(f"| `{name}` |")), None)
            if row is None:
                missing.append(f"[{t.name}] {name}")
                continue
            if ref._default(field) not in row:
                missing.append(f"[{t.name}] {name}: default")
    for path, model in ref.configuration_models().items():
        if path in ref.INTERNAL_MODELS:
            continue
        for name in model.model_fields:
            if f"| `{name}` |" not in page:
                missing.append(f"{path}.{name}")
    assert missing == []


def test_the_configuration_reference_names_the_flags_of_the_fields(ref):
    """A flag generated from a [tracker] field shows in that field's row."""
    page = ref.config_markdown()
    section = page.split("### `[tracker]`", 1)[1].split("\n### ", 1)[0]
    row = next(r for r in section.splitlines() if r.startswith("| `depth` |"))
    assert row.endswith("| `--depth` |")  # every command of the table: named in its heading
    assert "cli.md#track" in section.split("| TOML key |")[0]
    row = next(r for r in section.splitlines() if r.startswith("| `p_gate` |"))
    assert "`--p-gate` ([track](cli.md#track), [fusion](cli.md#fusion))" in row  # not eval
    row = next(r for r in page.splitlines() if r.startswith("| `mode` |") and "on" in r)
    assert "`--registration`" in row


def _section_literals() -> set[str]:
    """TOML table names the services read: ``section="x"`` keywords and defaults, the
    third argument of ``service_config(...)``, the second of ``load_toml(...)``, and
    assignments ``*_SECTION = "x"`` / ``section = "x" [if ... else ...]``."""
    names = set()
    for path in (ROOT / "services").rglob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.Call):
                fn = getattr(node.func, "id", getattr(node.func, "attr", ""))
                for kw in node.keywords:
                    if kw.arg == "section" and isinstance(kw.value, ast.Constant):
                        names.add(kw.value.value)
                pos = {"service_config": 2, "load_toml": 1}.get(fn)
                if pos is not None and len(node.args) > pos:
                    arg = node.args[pos]
                    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                        names.add(arg.value)
            elif isinstance(node, ast.Assign):
                value = node.value.body if isinstance(node.value, ast.IfExp) else node.value
                for target in node.targets:
                    named = isinstance(target, ast.Name) and (
                        target.id.endswith("_SECTION") or target.id == "section"
                    )
                    if named and isinstance(value, ast.Constant):
                        names.add(value.value)
            elif isinstance(node, ast.FunctionDef):
                a = node.args
                pairs = list(zip(a.args[len(a.args) - len(a.defaults) :], a.defaults))
                pairs += list(zip(a.kwonlyargs, a.kw_defaults))
                for arg, default in pairs:
                    if arg.arg == "section" and isinstance(default, ast.Constant):
                        names.add(default.value)
    names.discard(None)
    return names


def test_every_toml_table_the_services_read_is_documented(ref):
    found = _section_literals()
    assert {"tracker", "fusion", "transport", "registration"} <= found  # the scan works
    assert found <= {t.name for t in ref.TABLES}


def test_every_wire_model_field_and_key_is_in_the_wire_reference(ref):
    import skyfuse.schemas as schemas

    page = ref.wire_markdown()
    rows = ref.key_table()
    assert len(rows) >= 10
    for key, _, _ in rows:
        assert ref._rst_inline(key) in page
    for kind in schemas.MODELS:
        assert f"* `{kind}`:" in page
    missing = []
    for name, model in ref.wire_models().items():
        section = page.split(f"## `{name}` {{#{name.lower()}}}", 1)
        if len(section) != 2:
            missing.append(name)
            continue
        body = section[1].split("\n## ", 1)[0]
        missing += [f"{name}.{f}" for f in model.model_fields if f"| `{f}` |" not in body]
    assert missing == []


def test_units_are_read_from_descriptions(ref):
    assert ref.unit_of("Hold each batch this long to order radars, s") == "s"
    assert ref.unit_of("CV acceleration variance, m²/s⁴ (25: turning aircraft)") == "m²/s⁴"
    assert ref.unit_of("Azimuth where the sector sweep starts, rad clockwise from north") == "rad"
    assert ref.unit_of("Maximum target speed, m/s: two-point pairing") == "m/s"
    assert ref.unit_of("Fusion service id") == ""
