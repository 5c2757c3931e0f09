"""Base model shared by every wire message: strict, no unknown fields, no NaN/inf
unless a field says so, and a ``schema_version`` so consumers can detect drift."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

SCHEMA_VERSION = 4
"""Version of the payload models (in the Zenoh encoding, ``skyfuse.{Model}/{version}``):
1 the first; 2 adds the secondary-surveillance plot columns and the track identity
fields (:mod:`schemas.identity`); 3 the identity events (``identity_changed``,
``identity_conflict``, ``emergency``, ``spi``, with ``attribute``, ``value``,
``previous``), ``Track.mode_3a_changed`` and the identity counters of ``Status``; 4 adds
sensors beyond the rotating radar — the ``RadarSite`` kind ``wgs84``, its ``detection``
semantics (``sweep``/``reports``), ``report_timeout``, ``coverage`` polygon and
``max_altitude``, and the ``PlotBatch`` columns ``lat``/``lon`` (WGS-84 plots), ``sigma``
(per-plot horizontal σ) and ``v_east``/``v_north``/``sigma_velocity`` (reported velocity).
Models forbid unknown fields, so a consumer of an older version rejects a message that
uses the new ones."""

INT64_MIN = -(2**63)
INT64_MAX = 2**63 - 1
Int64 = Annotated[int, Field(ge=INT64_MIN, le=INT64_MAX)]
"""A JSON integer that fits a NumPy ``int64`` (columns become int64 arrays; a larger
integer would raise ``OverflowError`` instead of a validation error)."""
NonNegInt64 = Annotated[int, Field(ge=0, le=INT64_MAX)]
"""A non-negative :data:`Int64` (times in ns, counters, sequence numbers)."""


class WireModel(BaseModel):
    """Base of all skyfuse messages (JSON on the wire and in MCAP)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=False)

    def to_json_bytes(self) -> bytes:
        """Encode as compact UTF-8 JSON (the payload format on Zenoh and in MCAP)."""
        return self.__pydantic_serializer__.to_json(self, exclude_none=True)

    @classmethod
    def from_json_bytes(cls, data: bytes | bytearray | memoryview | str):
        """Decode and validate a JSON payload; raises ``pydantic.ValidationError``."""
        if isinstance(data, memoryview):
            data = bytes(data)
        return cls.model_validate_json(data)
