"""Per-radar systematic errors as scenario parameters (docs/concepts/registration.md).

Every polar radar ``ID`` of a scenario gets four parameters (``--param ID.KEY=VALUE``):

* ``ID.bias_azimuth_deg`` — azimuth offset b_ψ, degrees clockwise;
* ``ID.bias_range_m`` — range offset b_D, metres;
* ``ID.bias_range_gain_ppm`` — range gain error g, parts per million (D_m = (1 + g) D + b_D);
* ``ID.bias_time_ms`` — time-stamping offset b_t, milliseconds (reported = true + b_t);

all 0 by default (the model is eq. 1 of :mod:`fusion.frames.sensor_bias`). The values
are part of ``Scenario.params`` (recorded as metadata) and of every ``Truth`` message
(``Truth.radar_bias``), so evaluations can score a registration estimate.
"""

from __future__ import annotations

import dataclasses
import math

from skyfuse.fusion.frames.sensor_bias import SensorBias

from .scenario import Param, in_range
from .sensor import SensorConfig

_KEYS = (
    # (parameter suffix, SensorBias field, scale to SI, help, bound)
    ("bias_azimuth_deg", "azimuth", math.pi / 180.0, "azimuth offset, deg clockwise", 10.0),
    ("bias_range_m", "range", 1.0, "range offset, m", 10_000.0),
    ("bias_range_gain_ppm", "range_gain", 1e-6, "range gain error, ppm", 100_000.0),
    ("bias_time_ms", "time", 1e-3, "time-stamping offset, ms (reported = true + offset)", 60_000.0),
)


def bias_parameters(radar_ids: list[str]) -> dict[str, Param]:
    """The four bias parameters of each radar id, default 0."""
    out = {}
    for rid in radar_ids:
        for suffix, _, _, text, bound in _KEYS:
            out[f"{rid}.{suffix}"] = Param(0.0, f"radar {rid}: {text}", in_range(-bound, bound))
    return out


def site_bias(values: dict, radar_id: str) -> SensorBias:
    """The :class:`SensorBias` of ``radar_id`` from the scenario parameter values (SI)."""
    kw = {
        field: values.get(f"{radar_id}.{suffix}", 0.0) * scale for suffix, field, scale, *_ in _KEYS
    }
    return SensorBias(**kw)


def apply_site_biases(sensors: list[SensorConfig], values: dict) -> list[SensorConfig]:
    """``sensors`` with each polar radar's ``bias`` set from the parameter values."""
    out = []
    for cfg in sensors:
        if cfg.site.kind == "cartesian" or cfg.reports:
            out.append(cfg)
        else:
            out.append(dataclasses.replace(cfg, bias=site_bias(values, cfg.site.radar_id)))
    return out
