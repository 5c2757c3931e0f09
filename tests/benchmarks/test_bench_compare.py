"""Benchmark support: the fast geodetic paths equal their references, and the Stone Soup
comparison runs end to end at tiny sizes (skipped without stonesoup)."""

from __future__ import annotations

import importlib.util
import json
import sys

import numpy as np
import pymap3d
import pytest
from service_support import ROOT
from skyfuse.fusion.frames import SystemFrame
from skyfuse.fusion.frames.geodesy import enu_to_geodetic

SITE = (45.3, 19.9, 150.0)


def _points(n: int = 40, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack(
        [rng.uniform(-2e5, 2e5, n), rng.uniform(-2e5, 2e5, n), rng.uniform(-500, 1.2e4, n)]
    )


def test_enu_to_geodetic_matches_pymap3d():
    enu = _points()
    ref = pymap3d.enu2geodetic(enu[:, 0], enu[:, 1], enu[:, 2], *SITE)
    got = enu_to_geodetic(enu, *SITE)
    assert np.abs(got[0] - ref[0]).max() < 1e-9  # deg
    assert np.abs(got[1] - ref[1]).max() < 1e-9
    assert np.abs(got[2] - ref[2]).max() < 1e-4  # m


@pytest.mark.parametrize("kind", ["stereographic", "planar"])
def test_enu_jacobian_matches_central_differences(kind):
    """Analytic ENU → plane Jacobian vs central differences through pymap3d + pyproj."""
    fr = SystemFrame(kind, 44.8, 20.45)
    enu = _points()

    def ref_map(p):
        lat, lon, alt = pymap3d.enu2geodetic(p[:, 0], p[:, 1], p[:, 2], *SITE)
        x, y = fr._sterea.forward(lat, lon)
        return np.column_stack([x, y, alt])

    h = 1.0
    Jn = np.stack(
        [(ref_map(enu + h * e) - ref_map(enu - h * e)) / (2 * h) for e in np.eye(3)], axis=-1
    )
    pos, J = fr.enu_to_frame_with_jacobian(enu, *SITE)
    assert np.abs(pos - ref_map(enu)).max() < 1e-4
    assert np.abs(J - Jn).max() < 1e-6
    assert np.allclose(fr.enu_jacobian(enu, *SITE), J)


def test_velocity_to_enu_round_trip():
    """A local east/north velocity mapped to the plane by finite differences of the
    projection comes back unchanged from velocity_to_enu."""
    fr = SystemFrame.stereographic(44.8, 20.45)
    rng = np.random.default_rng(3)
    lat = 44.8 + rng.uniform(-1.5, 1.5, 20)
    lon = 20.45 + rng.uniform(-2, 2, 20)
    alt = rng.uniform(0, 11e3, 20)
    ve, vn = rng.uniform(-250, 250, 20), rng.uniform(-250, 250, 20)
    dt = 0.01
    lat1, lon1, alt1 = pymap3d.enu2geodetic(ve * dt, vn * dt, 0 * ve, lat, lon, alt)
    lat0, lon0, alt0 = pymap3d.enu2geodetic(-ve * dt, -vn * dt, 0 * ve, lat, lon, alt)
    x1, y1, _ = fr.from_geodetic(lat1, lon1, alt1)
    x0, y0, _ = fr.from_geodetic(lat0, lon0, alt0)
    x, y, z = fr.from_geodetic(lat, lon, alt)
    e, n, _ = fr.velocity_to_enu(x, y, z, (x1 - x0) / (2 * dt), (y1 - y0) / (2 * dt))
    assert np.abs(e - ve).max() < 1e-3
    assert np.abs(n - vn).max() < 1e-3


@pytest.mark.skipif(importlib.util.find_spec("stonesoup") is None, reason="needs stonesoup")
def test_compare_stonesoup_smoke(tmp_path):
    spec = importlib.util.spec_from_file_location(
        "compare_stonesoup", ROOT / "benchmarks" / "compare_stonesoup.py"
    )
    mod = importlib.util.module_from_spec(spec)
    sys.modules["compare_stonesoup"] = mod
    spec.loader.exec_module(mod)
    out = tmp_path / "h.json"
    rc = mod.main(
        ["--targets", "3", "--scans", "8", "--repeats", "1", "--clutter", "2",
         "--scenarios", "cartesian", "--json", str(out)]
    )  # fmt: skip
    assert rc == 0
    res = json.loads(out.read_text())
    assert len(res["cases"]) == 3
    for case in res["cases"]:
        for side in ("skyfuse", "stonesoup"):
            assert case[side]["ms_per_scan"] > 0
            assert case[side]["gospa_distance"] >= 0
        assert case["scans"] == 8
    # 3 well-separated targets: both trackers hold them after initiation (GOSPA c = 250 m:
    # a missed target costs 125 m, so the mean stays well under 3 missed targets)
    assert res["cases"][0]["skyfuse"]["gospa_distance"] < 3 * 125
