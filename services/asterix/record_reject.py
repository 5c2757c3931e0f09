"""A decoded ASTERIX record that is not usable, and the header every category checks first.

Every category's decoder returns either its report type or a :class:`RecordReject`:
``reason`` is a short count key from the category's ``REJECT_REASONS`` (``cat010_no_time``
…, a bounded vocabulary the stream counts), ``detail`` says which item, which value and
why, for the log. Nothing in decoding raises for a bad record.

:func:`source_and_time` is the header shared by CAT010 and CAT020 target reports (and by
CAT010 status messages): I0xx/010 data source (SAC, SIC) and I0xx/140 time of day (LSB
1/128 s), which must lie in one day (plus the second a day may run over at a leap
second). CAT021 takes its times from other items (edition-dependent) and CAT048 decodes
from spans or libasterix objects; both return the same :class:`RecordReject`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from .fields import DAY_S, time_of_day


@dataclass(slots=True)
class RecordReject:
    """A parsed record that is not usable: ``reason`` (a count key of the category's
    ``REJECT_REASONS``), ``detail`` (the item, the value, why), SAC/SIC when known."""

    reason: str
    detail: str
    sac: int | None = None
    sic: int | None = None


def source_and_time(
    items: Mapping[str, bytes], category: int
) -> tuple[int, int, float] | RecordReject:
    """(SAC, SIC, time of day in s) of a record given as item name → item bytes, or the
    reject ``cat0NN_no_data_source`` / ``_no_time`` / ``_bad_time``."""
    prefix = f"cat{category:03d}"
    b = items.get("010")
    if b is None:
        detail = f"record has no I{category:03d}/010 (SAC/SIC)"
        return RecordReject(f"{prefix}_no_data_source", detail)
    sac, sic = b[0], b[1]
    b = items.get("140")
    if b is None:
        detail = f"record has no I{category:03d}/140 time of day"
        return RecordReject(f"{prefix}_no_time", detail, sac, sic)
    tod = time_of_day(b)
    if tod >= DAY_S + 1.0:
        detail = f"I{category:03d}/140 time of day = {tod} s is outside one day"
        return RecordReject(f"{prefix}_bad_time", detail, sac, sic)
    return sac, sic, tod


def wgs84_reject(
    lat: float | None, lon: float | None, item: str, sac: int, sic: int
) -> RecordReject | None:
    """The reject ``cat0NN_bad_position`` of a WGS-84 position outside latitude ±90° /
    longitude ±180° (``item`` e.g. ``"I020/041"``: the item's LSB lets 32 bits encode
    more), or ``None`` for a position in range or absent."""
    if lat is None or lon is None or (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        return None
    detail = f"{item} latitude/longitude {lat:.5f}/{lon:.5f} outside WGS-84 ranges"
    return RecordReject(f"cat{item[1:4]}_bad_position", detail, sac, sic)
