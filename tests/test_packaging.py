"""The distribution installs one import package, ``skyfuse``: every repository package folder
(fusion/, schemas/, services/ and their sub-folders with an ``__init__.py``) is listed in
pyproject.toml under ``skyfuse.``, and no project module imports the bare folder names."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TOP = ("fusion", "schemas", "services")
DATA = ("recordings",)  # package data: the sample recording


def test_every_package_folder_is_installed_under_skyfuse():
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(cfg["packages"])
    on_disk = {
        "skyfuse." + ".".join(p.parent.relative_to(ROOT).parts)
        for top in (*TOP, *DATA)
        for p in (ROOT / top).rglob("__init__.py")
    }
    assert on_disk - listed == set(), "add these to [tool.setuptools] packages"
    assert listed - on_disk == set(), "these are listed but have no __init__.py"
    assert cfg["package-dir"] == {f"skyfuse.{t}": t for t in (*TOP, *DATA)}
    assert cfg["package-data"] == {"skyfuse.recordings": ["*.mcap"]}
    assert list((ROOT / "recordings").glob("*.mcap")), "the sample recording is missing"


def test_no_bare_top_level_imports():
    bare = re.compile(r"^\s*(from|import)\s+(fusion|schemas|services)\b", re.M)
    offenders = [
        str(p.relative_to(ROOT))
        for top in (*TOP, "tests", "benchmarks")
        for p in (ROOT / top).rglob("*.py")
        if bare.search(p.read_text(encoding="utf-8"))
    ]
    assert offenders == []
