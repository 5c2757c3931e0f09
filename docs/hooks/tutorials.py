"""The tutorials of the documentation site: each ``docs/tutorials/*.py`` is a plain Python
script, run at every docs build and rendered as a page with its prose, code and output.

Script format (the "percent" cell format of Jupytext and sphinx-gallery): the module
docstring is the page's introduction (Markdown, starting with its ``# Title``); lines
``# %%`` start a cell; the comment lines at the top of a cell are its prose (Markdown
without the leading ``# ``), the rest is its code. Cells run in order in one namespace
in a separate Python process (the interpreter running the build), with the standard output
of each cell captured and shown under it. A tutorial that raises fails the build.

``tests/docs/test_tutorials.py`` runs the same scripts under pytest.
"""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

#: Longest a tutorial may run, s.
TIMEOUT_S = 300

_RUNNER = r"""
import contextlib, io, json, sys
path, cells = json.load(sys.stdin)
ns = {"__name__": "__main__", "__file__": path}
outs = []
for start, code in cells:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        exec(compile("\n" * start + code, path, "exec"), ns)
    outs.append(buf.getvalue())
sys.stdout.write(json.dumps(outs))
"""


@dataclass
class Cell:
    prose: str
    code: str
    start: int  # 0-based line of the code's first line in the script


def split_script(source: str) -> tuple[str, list[Cell]]:
    """(the docstring, the cells) of a tutorial script."""
    tree = ast.parse(source)
    doc = ast.get_docstring(tree) or ""
    lines = source.splitlines()
    first = tree.body[0].end_lineno if doc else 0
    cells: list[Cell] = []
    block: list[tuple[int, str]] = []

    def close() -> None:
        i = 0
        prose = []
        while i < len(block) and block[i][1].startswith("#"):
            prose.append(block[i][1][2:] if block[i][1].startswith("# ") else "")
            i += 1
        code = block[i:]
        while code and not code[0][1].strip():
            code = code[1:]
        while code and not code[-1][1].strip():
            code = code[:-1]
        if prose or code:
            start = code[0][0] if code else 0
            cells.append(Cell("\n".join(prose).strip(), "\n".join(t for _, t in code), start))

    for n, line in enumerate(lines[first:], start=first):
        if line.strip() == "# %%":
            close()
            block = []
        else:
            block.append((n, line))
    close()
    return doc, cells


def run_cells(path: Path, cells: list[Cell]) -> list[str]:
    """The standard output of each cell, run in order in one fresh interpreter."""
    payload = json.dumps([str(path), [(c.start, c.code) for c in cells]])
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run(
        [sys.executable, "-c", _RUNNER],
        input=payload,
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        cwd=path.parent,
        env=env,
        check=False,
    )
    if proc.returncode != 0:
        raise RuntimeError(f"tutorial {path.name} failed:\n{proc.stderr[-4000:]}")
    return json.loads(proc.stdout)


def render(path: Path) -> str:
    """The Markdown page of one tutorial, with the output of its run."""
    doc, cells = split_script(path.read_text())
    outputs = run_cells(path, cells)
    title, _, intro = doc.partition("\n")
    out = [
        title,
        "",
        f"[Download the script]({path.name}) · run it with `python docs/tutorials/{path.name}`"
        " · this page shows the output of its last run at the documentation build.",
        "",
        intro.strip(),
        "",
    ]
    for cell, text in zip(cells, outputs, strict=True):
        if cell.prose:
            out += [cell.prose, ""]
        if cell.code:
            out += ["```python", cell.code, "```", ""]
        if text.strip():
            out += ['``` { .text .no-copy title="Output" }', text.rstrip("\n"), "```", ""]
    return "\n".join(out) + "\n"


def tutorials(docs_dir: str | Path) -> list[Path]:
    return sorted(Path(docs_dir, "tutorials").glob("*.py"))


def on_files(files, config):
    """Add one generated page per tutorial script (``tutorials/NAME.md``)."""
    from mkdocs.structure.files import File

    for path in tutorials(config["docs_dir"]):
        files.append(File.generated(config, f"tutorials/{path.stem}.md", content=render(path)))
    return files
