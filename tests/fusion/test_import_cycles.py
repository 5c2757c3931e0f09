"""No import cycles in ``fusion/``, and no import deferred into a function to dodge one.

The imports of every module under ``fusion/`` are read from its source (``ast``, nothing
is imported): module-level and function-level alike, since an import deferred into a
function still closes a cycle when the function runs. ``from P import name`` depends on
the module ``P.name`` when there is one, else on ``P``; importing a module also runs its
packages' ``__init__`` (an edge to each package above it that is not also above the
importer). A cycle is a strongly connected component of that graph with more than one
module. A function-level import of a skyfuse module must say why in a comment on its
line (``# start-up: …``: an optional heavy module kept out of the import), never a cycle.

The check is tested against small trees written here: a cycle through a package
``__init__`` and one through a deferred import are found, a tree without one is clean.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _modules(root: Path, top: str) -> dict[str, Path]:
    """Module name (``skyfuse.fusion.…``) → file, for every module under ``root/top``."""
    out = {}
    for path in (root / top).rglob("*.py"):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(["skyfuse", *parts])] = path
    return out


def _ancestors(name: str) -> set[str]:
    parts = name.split(".")
    return {".".join(parts[:i]) for i in range(1, len(parts))}


def _targets(node, name: str, is_package: bool, modules) -> list[str]:
    """The modules an import statement of module ``name`` depends on."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if node.level:
        base = name.split(".") if is_package else name.split(".")[:-1]
        base = base[: len(base) - (node.level - 1)]
        source = ".".join(base + ([node.module] if node.module else []))
    else:
        source = node.module
    return [f"{source}.{a.name}" if f"{source}.{a.name}" in modules else source for a in node.names]


def import_graph(root: Path, top: str = "fusion"):
    """(edges {module: set of modules}, function-level imports [(file, line, text)])."""
    modules = _modules(root, top)
    edges: dict[str, set[str]] = {m: set() for m in modules}
    deferred = []
    for name, path in modules.items():
        text = path.read_text(encoding="utf-8")
        tree = ast.parse(text)
        top_level = {id(n) for n in tree.body}
        lines = text.splitlines()
        for node in ast.walk(tree):
            if not isinstance(node, ast.Import | ast.ImportFrom):
                continue
            targets = _targets(node, name, path.name == "__init__.py", modules)
            own = _ancestors(name) | {name}
            for t in targets:
                edges[name] |= {u for u in {t} | (_ancestors(t) - own) if u in modules} - {name}
            if id(node) not in top_level and any(t.startswith("skyfuse.") for t in targets):
                deferred.append((path, node.lineno, lines[node.lineno - 1].strip()))
    return edges, deferred


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10_000))
    try:
        for v in edges:
            if v not in index:
                visit(v)
    finally:
        sys.setrecursionlimit(limit)
    return out


def test_fusion_has_no_import_cycle():
    edges, _ = import_graph(ROOT)
    assert len(edges) > 100  # the whole package was read
    assert cycles(edges) == []


def test_no_import_is_deferred_without_a_reason():
    _, deferred = import_graph(ROOT)
    unexplained = [
        f"{p.relative_to(ROOT)}:{n}: {t}" for p, n, t in deferred if "# start-up" not in t
    ]
    assert unexplained == []


def _tree(tmp_path: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        path = tmp_path / "fusion" / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return tmp_path


def test_the_check_finds_cycles_through_packages_and_deferred_imports(tmp_path):
    base = {
        "__init__.py": "",
        "a/__init__.py": "from .core import A\n",
        "a/core.py": "from ..b import helper\nA = 1\n",
        "b.py": "def helper():\n    from skyfuse.fusion.a.core import A\n    return A\n",
        "c.py": "from . import b\n",
    }
    edges, deferred = import_graph(_tree(tmp_path / "one", base))
    found = cycles(edges)
    assert found == [["skyfuse.fusion.a", "skyfuse.fusion.a.core", "skyfuse.fusion.b"]]
    assert [n for _, n, _ in deferred] == [2]
    # b importing the package a (not its module) closes the cycle through a/__init__ too
    base["b.py"] = "import skyfuse.fusion.a.other\n"
    base["a/other.py"] = "X = 2\n"
    edges, _ = import_graph(_tree(tmp_path / "two", base))
    assert cycles(edges) == [["skyfuse.fusion.a", "skyfuse.fusion.a.core", "skyfuse.fusion.b"]]
    # without the back edge: clean (a submodule importing a sibling is not a cycle)
    base["b.py"] = "def helper():\n    return 1\n"
    base["a/core.py"] = "from . import other\nfrom ..b import helper\nA = 1\n"
    edges, deferred = import_graph(_tree(tmp_path / "three", base))
    assert cycles(edges) == [] and deferred == []
