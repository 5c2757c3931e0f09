"""Base model shared by every wire message: strict, no unknown fields, no NaN/inf
unless a field says so, and a ``schema_version`` so consumers can detect drift."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

SCHEMA_VERSION = 1


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
