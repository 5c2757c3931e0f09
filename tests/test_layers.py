"""The layers of the README's Layout table, enforced: every import of every module of every
package (module-level and function-level, absolute and relative, parsed with ``ast``) goes
to the module's own package or to one the table's "may import" column allows.

``LAYERS`` is the table; ``test_readme_table_matches`` fails when the README's table and this
copy differ, so neither can drift from the other."""

from __future__ import annotations

import ast
import re
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# package -> what it may import besides itself (``everything above``: every row above it)
LAYERS: dict[str, tuple[str, ...] | str] = {
    "skyfuse.schemas": (),
    "skyfuse.fusion": ("skyfuse.schemas",),
    "skyfuse.services.runtime": ("skyfuse.schemas",),
    "skyfuse.services.asterix": ("skyfuse.schemas",),
    "skyfuse.services.recording": ("skyfuse.schemas", "skyfuse.services.runtime"),
    "skyfuse.services.sensors": (
        "skyfuse.fusion.sim",
        "skyfuse.schemas",
        "skyfuse.services.runtime",
        "skyfuse.services.asterix",
        "skyfuse.services.recording",
    ),
    "skyfuse.services.fusion": ("skyfuse.fusion", "skyfuse.schemas", "skyfuse.services.runtime"),
    "skyfuse.services.evaluation": (
        "skyfuse.fusion",
        "skyfuse.schemas",
        "skyfuse.services.fusion",
        "skyfuse.services.recording",
        "skyfuse.services.asterix",
        "skyfuse.services.runtime",
    ),
    "skyfuse.services.cli": "everything above",
    "skyfuse.recordings": (),
}
NAMESPACES = ("skyfuse", "skyfuse.services")
"""Parents of the table's packages: they hold no code and may import nothing of skyfuse."""


def allowed() -> dict[str, frozenset[str]]:
    """``LAYERS`` with ``everything above`` expanded."""
    out: dict[str, frozenset[str]] = {}
    for pkg, may in LAYERS.items():
        out[pkg] = frozenset(out) if may == "everything above" else frozenset(may)
    return out


# --- the README's table ---------------------------------------------------------------
def _expand(token: str) -> list[str]:
    """```services.{runtime,asterix}``` → ``skyfuse.services.runtime``, ``…asterix``."""
    m = re.fullmatch(r"([\w.]*)\{([\w,]+)\}", token)
    names = [m.group(1) + part for part in m.group(2).split(",")] if m else [token]
    return [f"skyfuse.{n}" for n in names]


def readme_layers() -> dict[str, tuple[str, ...] | str]:
    """The Layout table of README.md as ``LAYERS`` spells it."""
    text = (ROOT / "README.md").read_text()
    section = text.split("\n## Layout\n", 1)[1].split("\n## ", 1)[0]
    out: dict[str, tuple[str, ...] | str] = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 3 or not cells[0].startswith("`skyfuse."):
            continue
        pkg = cells[0].split("`")[1]
        may = re.sub(r"\([^)]*\)", "", cells[2]).strip()  # parenthesised notes are comments
        if may == "everything above":
            out[pkg] = may
        elif may in ("nothing of skyfuse", "—"):
            out[pkg] = ()
        else:
            out[pkg] = tuple(n for tok in re.findall(r"`([^`]+)`", may) for n in _expand(tok))
    return out


# --- the imports of a module ----------------------------------------------------------
def package_dirs() -> dict[str, Path]:
    """Import package → folder (pyproject's setuptools ``package-dir``)."""
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    return {pkg: ROOT / d for pkg, d in cfg["tool"]["setuptools"]["package-dir"].items()}


def modules() -> dict[str, tuple[Path, bool]]:
    """Every module of every package: name → (file, is a package ``__init__``)."""
    out = {}
    for pkg, folder in package_dirs().items():
        for f in sorted(folder.rglob("*.py")):
            parts = list(f.relative_to(folder).with_suffix("").parts)
            is_pkg = parts[-1] == "__init__"
            name = ".".join([pkg, *parts[:-1]] if is_pkg else [pkg, *parts])
            out[name] = (f, is_pkg)
    return out


def imported(source: str, module: str, is_pkg: bool, known: set[str]) -> list[tuple[int, str]]:
    """(line, module name) of every skyfuse import in ``source``, at any depth; ``from P
    import n`` names ``P.n`` when that is a module, else ``P``."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                here = module.split(".") if is_pkg else module.split(".")[:-1]
                up = here[: len(here) - (node.level - 1)]
                base = ".".join([*up, *([node.module] if node.module else [])])
            for a in node.names:
                sub = f"{base}.{a.name}"
                out.append((node.lineno, sub if sub in known else base))
    return [(line, m) for line, m in out if m == "skyfuse" or m.startswith("skyfuse.")]


def owner(module: str) -> str | None:
    """The table's package that ``module`` belongs to (the longest prefix)."""
    hits = [p for p in LAYERS if module == p or module.startswith(p + ".")]
    return max(hits, key=len) if hits else None


def _within(module: str, packages) -> bool:
    return any(module == p or module.startswith(p + ".") for p in packages)


def violations(source: str, module: str, is_pkg: bool, known: set[str]) -> list[str]:
    """Every import of ``module`` the table does not allow (``module:line imports target``);
    ``import skyfuse`` (the namespace, for its ``__path__``) imports no code and is allowed."""
    own = owner(module)
    may = (own, *allowed()[own]) if own else ()
    return [
        f"{module}:{line} imports {target}"
        for line, target in imported(source, module, is_pkg, known)
        if target != "skyfuse" and not _within(target, may)
    ]


# --- tests ----------------------------------------------------------------------------
def test_readme_table_matches():
    assert readme_layers() == LAYERS


def test_every_package_is_in_the_table():
    mods = modules()
    homeless = [m for m in mods if owner(m) is None and m not in NAMESPACES]
    assert homeless == []


@pytest.mark.parametrize("package", list(LAYERS))
def test_imports_follow_the_table(package: str):
    mods = modules()
    known = set(mods)
    bad = []
    for name, (path, is_pkg) in mods.items():
        if owner(name) == package:
            bad += violations(path.read_text(), name, is_pkg, known)
    assert bad == []


def test_namespace_packages_import_nothing():
    mods = modules()
    known = set(mods)
    for name in NAMESPACES:
        if name in mods:
            path, is_pkg = mods[name]
            assert imported(path.read_text(), name, is_pkg, known) == []


def test_the_check_finds_upward_and_hidden_imports():
    """The checker itself: a function-level import of the command line from a sensor, a
    relative import that climbs into ``services.cli``, ``fusion`` reaching ``services`` and
    ``schemas`` reaching ``fusion`` are all reported; allowed ones are not."""
    known = set(modules())
    src = "def f():\n    from skyfuse.services.cli.main import main\n"
    assert violations(src, "skyfuse.services.sensors.simulated", False, known) == [
        "skyfuse.services.sensors.simulated:2 imports skyfuse.services.cli.main"
    ]
    src = "from ..cli import main\n"
    assert violations(src, "skyfuse.services.runtime.transport", False, known) == [
        "skyfuse.services.runtime.transport:1 imports skyfuse.services.cli.main"
    ]
    assert violations("import skyfuse.services.runtime\n", "skyfuse.fusion.sim", True, known)
    assert violations("from skyfuse.fusion import sim\n", "skyfuse.schemas.keys", False, known)
    # a sensor may import fusion.sim, but not the rest of the tracking library
    assert not violations(
        "from skyfuse.fusion import sim\n", "skyfuse.services.sensors.x", False, known
    )
    assert violations("import skyfuse.fusion.tracker\n", "skyfuse.services.sensors.x", False, known)
    assert not violations("from . import keys\n", "skyfuse.schemas", True, known)
