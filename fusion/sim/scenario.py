"""``Scenario``: everything the simulator needs (targets, sensors, frame, timing), and the
typed scenario parameters with validation (``Param``)."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import numpy as np
from skyfuse.fusion.frames import Stereographic
from skyfuse.schemas import FrameKind, FrameSpec, RadarSite

from .sensor import SensorConfig
from .trajectories import TargetSet

DEFAULT_START_TIME = 1_767_225_600_000_000_000
"""2026-01-01T00:00:00Z in ns since the Unix epoch: the default scenario epoch."""


@dataclass
class Scenario:
    """A built scenario.

    * ``sites``: the wire ``RadarSite`` of every sensor (same order as ``sensors``).
    * ``frame``: PLANAR (x east, y north, m; lat0/lon0 = plane origin, mapped to WGS-84
      with the stereographic projection at that origin) or STEREOGRAPHIC (system plane
      centred at lat0/lon0, [Dikić]).
    * ``duration`` s, ``start_time`` ns UTC, ``n_targets``; ``params``: every parameter
      with its value (for recording as metadata); ``truth_period`` s.
    * ``targets`` (trajectories in the plane + height), ``sensors`` (simulation config),
      ``plane`` (the projection that maps plane x/y to lat/lon).
    """

    name: str
    description: str
    sites: list[RadarSite]
    frame: FrameSpec
    duration: float
    start_time: int
    n_targets: int
    params: dict[str, Any]
    targets: TargetSet
    sensors: list[SensorConfig]
    plane: Stereographic
    truth_period: float
    seed: int

    @property
    def planar(self) -> bool:
        return self.frame.kind == FrameKind.PLANAR

    def geodetic(self, index, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(lat deg, lon deg, height m above WGS-84) of targets ``index`` at ``t`` s."""
        p, _ = self.targets.state(t, index)
        lat, lon = self.plane.inverse(p[..., 0], p[..., 1])
        return lat, lon, p[..., 2]

    def metadata(self) -> dict[str, str]:
        """String metadata (e.g. for an MCAP metadata record): name, description and
        every parameter as JSON."""
        return {
            "scenario": self.name,
            "description": self.description,
            "params": json.dumps(self.params, sort_keys=True),
            "frame": self.frame.model_dump_json(),
        }


@dataclass(frozen=True)
class Param:
    """A scenario parameter: its default (whose type is the parameter's type), a help
    text, and optional allowed ``choices`` or a ``check`` returning a reason if bad."""

    default: Any
    help: str
    check: Callable[[Any], str | None] | None = None
    choices: tuple | None = None


def positive(v) -> str | None:
    return None if v > 0 else "must be > 0"


def non_negative(v) -> str | None:
    return None if v >= 0 else "must be >= 0"


def probability(v) -> str | None:
    return None if 0.0 < v <= 1.0 else "must be in (0, 1]"


def in_range(lo: float, hi: float) -> Callable[[Any], str | None]:
    def check(v) -> str | None:
        return None if lo <= v <= hi else f"must be in [{lo}, {hi}]"

    return check


def parse_start_time(value) -> int:
    """ns UTC from an int (ns), or an ISO-8601 string with time zone (e.g. 2026-01-01T00:00:00Z)."""
    if isinstance(value, str):
        try:
            return int(value)
        except ValueError:
            pass
        dt = datetime.fromisoformat(value.replace("Z", "+00:00"))
        if dt.tzinfo is None:
            raise ValueError("has no time zone (use e.g. 2026-01-01T00:00:00Z)")
        return round(dt.timestamp()) * 1_000_000_000 + dt.microsecond * 1000
    if isinstance(value, bool) or not float(value).is_integer():
        raise ValueError("must be an integer number of ns")
    return int(value)


def coerce(scenario: str, name: str, value, param: Param):
    """Convert ``value`` to the parameter's type and validate it; ``ValueError`` names the
    scenario, the parameter, the value and the reason."""

    def fail(reason: str):
        raise ValueError(f"scenario {scenario!r}: parameter {name!r} = {value!r}: {reason}")

    default = param.default
    try:
        if name == "start_time":
            out = parse_start_time(value)
        elif isinstance(default, bool):
            if isinstance(value, str) and value.lower() in ("true", "1", "yes", "false", "0", "no"):
                out = value.lower() in ("true", "1", "yes")
            elif isinstance(value, bool | int | np.bool_) and value in (0, 1):
                out = bool(value)
            else:
                fail("must be a boolean")
        elif isinstance(default, int):
            f = float(value)
            if isinstance(value, bool) or not f.is_integer():
                fail("must be an integer")
            out = int(f)
        elif isinstance(default, float):
            if isinstance(value, bool):
                fail("must be a number")
            out = float(value)
            if not math.isfinite(out):
                fail("must be finite")
        else:
            out = str(value)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ValueError) and str(exc).startswith(f"scenario {scenario!r}"):
            raise
        fail(str(exc) or "wrong type")
    if param.choices is not None and out not in param.choices:
        fail(f"must be one of {', '.join(map(str, param.choices))}")
    if param.check is not None:
        reason = param.check(out)
        if reason:
            fail(reason)
    return out
