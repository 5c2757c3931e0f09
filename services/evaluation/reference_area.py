"""The assessed area of ``skyfuse eval --reference``: ``--score-area`` polygons (WGS-84)
read and placed in the evaluation frame (the scoring: :mod:`skyfuse.fusion.metrics
.reference_coverage`).

Each ``--score-area`` value (the flag may be repeated) is either

* a TOML file with one or more polygons::

      [[area]]
      name = "manoeuvring area"          # optional
      vertices = [[41.2930, 2.0610], [41.2930, 2.1050], [41.3060, 2.1050], [41.3060, 2.0610]]

  (``[lat, lon]`` degrees, at least 3 vertices, closed implicitly), or
* one polygon inline, ``"LAT LON; LAT LON; LAT LON; ..."``.

A target is in the area when it is inside any of the polygons (even-odd rule). Errors —
a missing file, bad TOML, a polygon with fewer than 3 vertices or a coordinate out of
range — are :class:`~skyfuse.services.evaluation.inputs.InputError` naming the polygon
and the vertex.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from skyfuse.services.evaluation.inputs import InputError

MAX_VERTICES = 10_000


@dataclass(frozen=True)
class AreaPolygon:
    """One polygon: ``name``, ``vertices`` (k, 2) [lat, lon] degrees."""

    name: str
    vertices: np.ndarray


def _vertices(raw, where: str) -> np.ndarray:
    """(k, 2) [lat, lon] from a list of pairs; InputError naming ``where``."""
    if not isinstance(raw, list | tuple) or not 3 <= len(raw) <= MAX_VERTICES:
        n = len(raw) if isinstance(raw, list | tuple) else type(raw).__name__
        raise InputError(f"{where}: {n} vertices: a polygon needs 3..{MAX_VERTICES} "
                         "[lat, lon] pairs", usage=True)  # fmt: skip
    out = np.empty((len(raw), 2))
    for i, v in enumerate(raw):
        ok = isinstance(v, list | tuple) and len(v) == 2
        ok = ok and all(isinstance(c, int | float) and not isinstance(c, bool) for c in v)
        if not ok:
            raise InputError(f"{where}: vertex {i} = {v!r}: must be [lat, lon] degrees",
                             usage=True)  # fmt: skip
        lat, lon = float(v[0]), float(v[1])
        if not (math.isfinite(lat) and -90 <= lat <= 90 and math.isfinite(lon)
                and -180 <= lon <= 180):  # fmt: skip
            raise InputError(f"{where}: vertex {i} = [{lat}, {lon}]: latitude must be in "
                             "[-90, 90], longitude in [-180, 180]", usage=True)  # fmt: skip
        out[i] = lat, lon
    return out


def _from_toml(path: Path) -> list[AreaPolygon]:
    try:
        with path.open("rb") as f:
            data = tomllib.load(f)
    except OSError as e:
        raise InputError(f"score area {str(path)!r}: {e.strerror or e}", usage=True) from None
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"score area {str(path)!r}: not valid TOML: {e}", usage=True) from None
    areas = data.get("area")
    if not isinstance(areas, list) or not areas or not all(isinstance(a, dict) for a in areas):
        raise InputError(f"score area {str(path)!r}: needs one or more [[area]] tables with "
                         "vertices = [[lat, lon], ...]", usage=True)  # fmt: skip
    out = []
    for i, a in enumerate(areas):
        name = str(a.get("name", f"{path.name}[{i}]"))
        if "vertices" not in a:
            raise InputError(f"score area {str(path)!r}, [[area]] {i} ({name}): no vertices",
                             usage=True)  # fmt: skip
        out.append(AreaPolygon(name, _vertices(a["vertices"], f"score area {name!r}")))
    return out


def _inline(text: str) -> AreaPolygon:
    pairs = []
    for part in text.split(";"):
        nums = part.split()
        try:
            pairs.append([float(c) for c in nums])
        except ValueError:
            pairs.append(nums)
    return AreaPolygon(text[:40], _vertices(pairs, f"score area {text!r}"))


def read_score_area(values: list[str] | None) -> list[AreaPolygon]:
    """The polygons of the ``--score-area`` values (module docstring); InputError."""
    out: list[AreaPolygon] = []
    for v in values or []:
        v = v.strip()
        if ";" in v:
            out.append(_inline(v))
        elif v:
            path = Path(v)
            if not path.is_file():
                hint = "give a TOML file or an inline polygon 'LAT LON; LAT LON; LAT LON'"
                raise InputError(f"score area {v!r}: no such file ({hint})", usage=True)
            out.extend(_from_toml(path))
    return out


def area_in_frame(polygons: list[AreaPolygon], frame) -> tuple[np.ndarray, ...]:
    """The polygons' vertices in ``frame``'s plane, (k, 2) m each (x east, y north)."""
    from skyfuse.services.fusion.adapter import coverage_polygon

    return tuple(coverage_polygon(frame, p.vertices.tolist()) for p in polygons)


def area_summary(polygons: list[AreaPolygon], cfg) -> dict | None:
    """The assessed area as JSON (None when it restricts nothing): the polygons' count,
    vertices and bounds (not the vertices themselves: an airport's manoeuvring area is
    hundreds of polygons), the minimum surface speed."""
    if not polygons and not cfg.min_surface_speed > 0:
        return None
    allv = np.concatenate([p.vertices for p in polygons]) if polygons else np.zeros((0, 2))
    return {
        "polygons": len(polygons),
        "vertices": len(allv),
        "names": [p.name for p in polygons[:20]],
        "lat_lon_min": allv.min(axis=0).tolist() if len(allv) else None,
        "lat_lon_max": allv.max(axis=0).tolist() if len(allv) else None,
        "min_surface_speed": cfg.min_surface_speed,
        "speed_span_s": cfg.speed_span_s,
    }
