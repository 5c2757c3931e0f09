"""The tutorials of the documentation site (docs/tutorials/*.py) run, cell by cell, as
the docs build runs them (docs/hooks/tutorials.py), and say what their pages claim."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("*.py"))


def _hook():
    path = ROOT / "docs" / "hooks" / "tutorials.py"
    spec = importlib.util.spec_from_file_location("docs_hooks_tutorials", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def outputs() -> dict[str, str]:
    hook = _hook()
    out = {}
    for path in TUTORIALS:
        _, cells = hook.split_script(path.read_text())
        out[path.stem] = "".join(hook.run_cells(path, cells))
    return out


def test_the_three_tutorials_exist():
    assert {p.stem for p in TUTORIALS} >= {"own_detections", "compare_trackers", "custom_density"}


def test_cells_keep_their_line_numbers():
    """Cells are compiled at their own lines, so a traceback points into the script."""
    hook = _hook()
    source = (ROOT / "docs" / "tutorials" / "own_detections.py").read_text().splitlines()
    _, cells = hook.split_script("\n".join(source))
    coded = [c for c in cells if c.code]
    assert len(coded) >= 4
    for cell in coded:
        assert source[cell.start] == cell.code.splitlines()[0]


def test_own_detections_confirms_the_two_aircraft_near_the_truth(outputs):
    text = outputs["own_detections"]
    xy = [tuple(map(float, m)) for m in re.findall(r"\(\s*(-?\d+),\s*(-?\d+)\) m,", text)]
    assert len(xy) == 2
    truth = [(11200.0, 5000.0), (10000.0, 8400.0)]  # the script's final true positions
    for x, y in xy:
        assert min(abs(x - tx) + abs(y - ty) for tx, ty in truth) < 400.0
    latlon = re.findall(r"lat (\d+\.\d+)°, lon (\d+\.\d+)°", text)
    assert len(latlon) == 2


def test_compare_trackers_scores_every_variant(outputs):
    rows = re.findall(r"^(\S+(?: N=\d)?)\s+(\d+\.\d) m", outputs["compare_trackers"], re.M)
    assert {name for name, _ in rows} == {"ipda", "its N=3", "lmits N=3", "jits N=3", "gnn"}
    assert all(float(g) < 40.0 for _, g in rows)  # GOSPA, c = 25 m: mostly localisation


def test_custom_density_matches_the_built_in_one(outputs):
    text = outputs["custom_density"]
    assert "same tracks: True" in text
    diff = float(re.search(r"largest state difference (\S+)", text).group(1))
    assert diff < 1e-6
