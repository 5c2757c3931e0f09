"""Record-by-record parsing of one data block with libasterix.

ASTERIX records carry no length: a record ends where its last item ends, so one bad
record makes the rest of its block unreadable. Parsing record by record keeps every
record before the bad one; the failure is reported as text (libasterix returns
``ValueError`` objects instead of raising) and the caller counts it.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from asterix.base import Bits, ParsingMode


class RecordError(str):
    """The reason a record could not be parsed (the rest of the block is lost)."""


def iter_records(spec: Any, data: bytes) -> Iterator[Any]:
    """Yield libasterix ``Record`` objects of ``spec`` (e.g. ``Cat_048_1_32``) parsed
    from a block's record bytes, then at most one :class:`RecordError`."""
    bits = Bits.from_bytes(data)
    record_cls = spec.cv_uap.cv_record
    while len(bits) > 0:
        try:
            result = record_cls.parse(ParsingMode.StrictParsing, bits)
        except Exception as exc:  # libasterix signals with return values; be safe anyway
            yield RecordError(f"{type(exc).__name__}: {exc}")
            return
        if isinstance(result, ValueError):
            yield RecordError(str(result.args[0]) if result.args else "parse error")
            return
        record, bits = result
        yield record


def quantity(record: Any, item: str, unit: str) -> float | None:
    """Physical value of a top-level Element item (``None`` if absent)."""
    it = record.get_item(item)
    if it is None:
        return None
    return it.variation.content.as_quantity(unit)


def sub_quantity(variation: Any, name: str, unit: str) -> float:
    """Physical value of an Element subitem of a Group/Compound variation."""
    return variation.get_item(name).variation.content.as_quantity(unit)


def sub_uint(variation: Any, name: str) -> int:
    """Raw unsigned value of a subitem of a Group/Extended variation."""
    return variation.get_item(name).as_uint()


def item_bytes(record: Any) -> dict[str, bytes]:
    """The bytes of each present top-level item of a parsed libasterix record, by item
    name (the form :mod:`.layout` splits a record into): decoders that convert item
    bytes themselves use it to read what libasterix parsed."""
    return {name: nsp.unparse().to_bytes() for name, nsp in record.items_regular.items()}
