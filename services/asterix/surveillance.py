"""Target reports of ADS-B (CAT021), multilateration and surface radar (CAT010, CAT020).

:class:`SurveillanceDecoder` turns the record bytes of one data block of these
categories into typed reports (:class:`.cat010.Cat010Report` /
:class:`.cat010.Cat010Status`, :class:`.cat020.Cat020Report`,
:class:`.cat021.Cat021Report`) with ``time_ns`` resolved by the caller's
:class:`.reader.TimeOfDayResolver`. :class:`.reader.AsterixStreamDecoder` routes these
categories here (its framing, duplicate filter, clock and counters are shared), and
:func:`read_reports` reads a whole pcap or raw file.

Per block, like the CAT048 path: the compiled layout (:mod:`.layout`) splits the
records while they are well formed; from the first record it declines, libasterix
parses the rest of the block and gives the error (``catNNN_malformed_record``; the
rest of that block is lost: ASTERIX records carry no length). Unusable records are
counted by their reject reason (``cat010.REJECT_REASONS`` …), never raised.

CAT021 edition: ``cat021_edition`` names one of :data:`.cat021.EDITIONS`, or
``"auto"``: per data source (SAC/SIC of the block's first record) the edition of the
source's previous block is used while its records decode to usable reports; otherwise
each of :data:`.cat021.AUTO_CANDIDATES` (2.7, a superset of the 2.x layouts, then 0.23)
is tried on the whole block, and the first under which every record is usable is kept
(``cat021_edition_changes`` counts switches after the first choice).

Counts: ``catNNN_records``, ``cat010_target_reports``, ``cat010_status_messages``,
``cat010_track_ends``, ``cat021_edition_X_Y`` (blocks per edition),
``catNNN_test_target`` (TST = 1, dropped), ``catNNN_simulated`` (SIM = 1, kept), the
reject reasons, ``duplicate_records``.
"""

from __future__ import annotations

from collections import Counter, OrderedDict
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from . import cat010, cat020, cat021
from .record_reject import RecordReject
from .records import RecordError, iter_records

CATEGORIES = frozenset({10, 20, 21})
MAX_SOURCES = 1024
Report = cat010.Cat010Report | cat010.Cat010Status | cat020.Cat020Report | cat021.Cat021Report


class SurveillanceDecoder:
    """Block-by-block decoder of CAT010/CAT020/CAT021 (see the module docstring).

    ``stats``: the caller's counters; ``note``: takes a problem in words;
    ``resolve``: ``(time of day s, receive time ns | None) -> ns UTC``;
    ``is_duplicate``: ``(category, record bytes) -> bool`` (a duplicate is skipped)."""

    def __init__(
        self,
        *,
        stats: Counter,
        note: Callable[[str], None],
        resolve: Callable[[float, int | None], int],
        is_duplicate: Callable[[int, bytes], bool] = lambda cat, raw: False,
        cat021_edition: str = "auto",
        fast: bool = True,
    ) -> None:
        if cat021_edition != "auto" and cat021_edition not in cat021.EDITIONS:
            known = ", ".join(cat021.EDITIONS)
            raise ValueError(f"cat021_edition = {cat021_edition!r}: not 'auto' or one of {known}")
        self.stats = stats
        self.note = note
        self.resolve = resolve
        self.is_duplicate = is_duplicate
        self.cat021_edition = cat021_edition
        self.fast = fast
        self._edition_of: OrderedDict[tuple[int, int], str] = OrderedDict()

    def decode_block(self, cat: int, data: bytes, recv_ns: int | None, where: str) -> list[Any]:
        """The usable reports of one block's record bytes, times resolved."""
        records: Iterable | None = None
        if cat == cat021.CATEGORY:
            edition, records = self._cat021_edition(data)
            self.stats[f"cat021_edition_{edition.replace('.', '_')}"] += 1
            fast = lambda d, p: cat021.decode_fast(d, p, edition)  # noqa: E731
            spec, lib = cat021.EDITIONS[edition], lambda r: cat021.decode_record(r, edition)
        elif cat == cat010.CATEGORY:
            fast, spec, lib = cat010.decode_fast, cat010.SPEC, cat010.decode_record
        elif cat == cat020.CATEGORY:
            fast, spec, lib = cat020.decode_fast, cat020.SPEC, cat020.decode_record
        else:
            raise ValueError(f"category {cat} is not one of {sorted(CATEGORIES)}")
        if records is None:
            records = self._records(cat, data, fast, spec, lib, where)
        out: list[Any] = []
        for raw, rec in records:
            self._keep(cat, raw, rec, recv_ns, out)
        return out

    def _records(self, cat: int, data: bytes, fast, spec, lib, where: str) -> Iterable:
        """(record bytes, decoded record) of a block: fast path, then libasterix."""
        pos, index, n = 0, 0, len(data)
        while self.fast and pos < n:
            got = fast(data, pos)
            if got is None:
                break
            yield data[pos : got[1]], got[0]
            pos, index = got[1], index + 1
        if pos >= n:
            return
        for rec in iter_records(spec, data[pos:]):
            if isinstance(rec, RecordError):
                self.stats[f"cat{cat:03d}_malformed_record"] += 1
                self.note(
                    f"{where}: CAT{cat:03d} block, record {index + 1}: {rec}; "
                    "the rest of the block is skipped"
                )
                return
            yield rec.unparse().to_bytes(), lib(rec)
            index += 1

    def _keep(self, cat: int, raw: bytes, rec: Any, recv_ns: int | None, out: list) -> None:
        prefix = f"cat{cat:03d}"
        self.stats[f"{prefix}_records"] += 1
        if self.is_duplicate(cat, raw):
            return
        if isinstance(rec, RecordReject):
            self.stats[rec.reason] += 1
            if self.stats[rec.reason] <= 3:
                self.note(f"CAT{cat:03d} record skipped: {rec.detail}")
            return
        if isinstance(rec, cat010.Cat010Status):
            self.stats["cat010_status_messages"] += 1
        else:
            if rec.tst:
                self.stats[f"{prefix}_test_target"] += 1
                return
            if rec.sim:
                self.stats[f"{prefix}_simulated"] += 1
            if isinstance(rec, cat010.Cat010Report):
                self.stats["cat010_target_reports"] += 1
                if rec.last and rec.x_m is None and rec.rho_m is None and rec.lat is None:
                    self.stats["cat010_track_ends"] += 1
        rec.time_ns = self.resolve(rec.tod, recv_ns)
        out.append(rec)

    def _cat021_edition(self, data: bytes) -> tuple[str, list | None]:
        """The edition of a CAT021 block, and its decoded records when the source's
        current edition decoded them all to usable reports (else ``None``)."""
        if self.cat021_edition != "auto":
            return self.cat021_edition, None
        source = _first_source(data)
        current = self._edition_of.get(source)
        if current is not None and self.fast:
            decoded = _all_usable(data, current)
            if decoded is not None:
                return current, decoded
        elif current is not None and cat021.block_fits(data, current):
            return current, None
        for edition in cat021.AUTO_CANDIDATES:
            if edition != current and cat021.block_fits(data, edition):
                if current is not None:
                    self.stats["cat021_edition_changes"] += 1
                    self.note(f"CAT021 source {source}: edition {current} → {edition}")
                self._edition_of[source] = edition
                self._edition_of.move_to_end(source)
                if len(self._edition_of) > MAX_SOURCES:
                    self._edition_of.popitem(last=False)
                return edition, None
        return current or cat021.AUTO_CANDIDATES[0], None


def _all_usable(data: bytes, edition: str) -> list | None:
    """(record bytes, report) of every record of a CAT021 block decoded by the fast path
    in ``edition``, or ``None`` if one record does not split or is not usable."""
    out, pos, n = [], 0, len(data)
    while pos < n:
        got = cat021.decode_fast(data, pos, edition)
        if got is None or not isinstance(got[0], cat021.Cat021Report):
            return None
        out.append((data[pos : got[1]], got[0]))
        pos = got[1]
    return out


def _first_source(data: bytes) -> tuple[int, int]:
    """SAC/SIC of a block's first record (I010 is the first UAP item of every CAT021
    edition), or (-1, -1)."""
    end = 0
    while end < len(data) and data[end] & 1:
        end += 1
    if end + 2 < len(data) and data[0] & 0x80:
        return data[end + 1], data[end + 2]
    return -1, -1


def read_reports(path: str | Path, **options: Any) -> tuple[list[Any], dict[str, int], list[str]]:
    """All reports of a pcap or raw file in file order, with the reader's counts and
    first problems in words: :class:`.reader.AsterixStreamDecoder` (``options`` as its
    keywords: ``date``, ``dedup``, ``cat021_edition``, ``fast`` …) with a report sink.
    CAT048/CAT034 in the same file are decoded too (and dropped here)."""
    from .pcap import iter_file_datagrams
    from .reader import AsterixStreamDecoder

    reports: list[Any] = []
    options.setdefault("report_batches", False)
    decoder = AsterixStreamDecoder(report_sink=reports.append, **options)
    for dgram in iter_file_datagrams(path, decoder.stats):
        decoder.feed_with_types(dgram)
    decoder.flush_with_types()
    return reports, dict(decoder.stats), list(decoder.messages)


def columns(reports: Iterable[Any], fields: Iterable[str]) -> dict[str, np.ndarray]:
    """Reports of one kind as NumPy columns (``None`` → NaN for numbers); ``fields``
    are attribute names, e.g. ``("time_ns", "x_m", "y_m", "mode_s")``. Integer columns
    with a missing value become float."""
    rows = list(reports)
    out: dict[str, np.ndarray] = {}
    for name in fields:
        values = [getattr(r, name) for r in rows]
        if any(isinstance(v, str) for v in values):
            out[name] = np.array(values, dtype=object)
        elif any(v is None for v in values) or any(isinstance(v, float) for v in values):
            out[name] = np.array([np.nan if v is None else v for v in values], dtype=float)
        else:
            out[name] = np.array(values, dtype=np.int64)
    return out
