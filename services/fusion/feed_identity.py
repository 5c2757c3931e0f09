"""The identity fields of the feed's ``Track`` rows, from the tracker's arrays.

:class:`~skyfuse.fusion.tracker.identity.TrackIdentity` (the tracks' codes, flight level,
SPI, downlinked parameters and their times) → the optional fields of
:class:`schemas.Track` (names and units of :mod:`schemas.identity`), only those a row
has: ``mode_3a``, ``mode_s``, ``callsign``, ``flight_level``, each with its ``*_time``
(when a plot last confirmed it, ns UTC); ``mode_3a_changed`` (CAT062 I062/060 CH),
``emergency`` (from a Mode-3/A code 7500, 7600 or 7700), ``spi`` (only when set); the
downlinked parameters of the last plot that carried their register with the register's
time (``intention_time``: BDS 4,0, ``track_turn_time``: 5,0, ``heading_speed_time``:
6,0); ``ssr_time`` and ``mode_s_update_time`` (the last update by a plot with an SSR /
a Mode S reply). A track without identity gets no field at all (its row is what it was
before identity existed).

The rows are built by which identity fields they have (:data:`FIELDS`, a bit each): the
fields' values are taken out of the arrays once per message, and the rows of one pattern
are made by one ``dict(zip())`` each, never field by field.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from operator import itemgetter

import numpy as np
from skyfuse.fusion.tracker.identity import (
    BLOCK_WIDTH,
    BLOCKS,
    CALLSIGN,
    CODE_NAMES,
    DOWNLINK_NAMES,
    LAYOUT,
    MODE_3A,
    MODE_S_REPLY,
    REGISTER_COLUMNS,
    SSR,
    TrackIdentity,
    is_emergency,
    unpack_callsigns,
)
from skyfuse.schemas.identity import EMERGENCY_CODES

REGISTER_TIMES = ("intention_time", "track_turn_time", "heading_speed_time")
"""The ``Track`` field of each register's time (BDS 4,0, 5,0, 6,0)."""
FIELDS = (
    *(f"{name}{end}" for name in CODE_NAMES for end in ("", "_time")),
    "mode_3a_changed", "emergency", "spi", "flight_level", "flight_level_time",
    *(f for r, cols in enumerate(REGISTER_COLUMNS)
      for f in (*(DOWNLINK_NAMES[j] for j in cols), REGISTER_TIMES[r])),
    "ssr_time", "mode_s_update_time",  # the reply_time columns SSR, MODE_S_REPLY
)  # fmt: skip
"""The identity fields of a ``Track`` row, in the order a row lists those it has."""
_BITS = 1 << np.arange(len(FIELDS), dtype=np.int64)
_OFFSET = dict(zip(BLOCKS, np.cumsum([0, *BLOCK_WIDTH.values()]).tolist()))
_EMERGENCY, _CALLSIGN = sum(BLOCK_WIDTH.values()), sum(BLOCK_WIDTH.values()) + 1
"""The columns after the blocks': emergency (its name) and the callsign (its text)."""


def _column(name: str, k: int = 0) -> int:
    """The column of :class:`TrackIdentity` field ``name`` (its k-th) among the blocks'."""
    block, cols = LAYOUT[name]
    return _OFFSET[block] + (cols.start + k if isinstance(cols, slice) else cols)


def _sources() -> tuple[np.ndarray, list[int]]:
    """For each of :data:`FIELDS`: the column saying whether a row has it, the column of
    its value (among the blocks' columns, :data:`_EMERGENCY`, :data:`_CALLSIGN`)."""
    src = {}
    for k, name in enumerate(CODE_NAMES):
        code = _column("codes", k)
        src[name] = (code, _CALLSIGN if k == CALLSIGN else code)
        src[f"{name}_time"] = (code, _column("code_time", k))
    level = _column("flight_level")
    src |= {"mode_3a_changed": (_column("mode_3a_changed"),) * 2,
            "emergency": (_EMERGENCY, _EMERGENCY), "spi": (_column("spi"),) * 2,
            "flight_level": (level, level),
            "flight_level_time": (level, _column("flight_level_time")),
            "ssr_time": (_column("reply_time", SSR),) * 2,
            "mode_s_update_time": (_column("reply_time", MODE_S_REPLY),) * 2}  # fmt: skip
    src |= {name: (_column("downlink", j),) * 2 for j, name in enumerate(DOWNLINK_NAMES)}
    src |= {name: (_column("downlink_time", r),) * 2 for r, name in enumerate(REGISTER_TIMES)}
    has, value = zip(*(src[f] for f in FIELDS))
    return np.array(has), list(value)


_HAS, _VALUE = _sources()
_DOWNLINK = _column("downlink") - _OFFSET["reals"] + np.arange(len(DOWNLINK_NAMES))
_REGISTER_OF = np.zeros(len(DOWNLINK_NAMES), np.int64)
for _r, _cols in enumerate(REGISTER_COLUMNS):
    _REGISTER_OF[_cols] = _column("downlink_time", _r)


def identity_fields(ident: TrackIdentity) -> tuple[np.ndarray, list[list]]:
    """(n, :data:`FIELDS`) bool: which rows have which field, and each field's values
    (plain lists of n; a value where a row lacks the field is never read)."""
    ints, reals, flags = ident.ints, ident.reals, ident.flags
    finite = np.isfinite(reals)
    finite[:, _DOWNLINK] &= ints[:, _REGISTER_OF] >= 0  # a parameter of a register reported
    mode_3a = ints[:, _column("codes", MODE_3A)]
    emergency = is_emergency(mode_3a)
    present = np.concatenate((ints >= 0, finite, flags, emergency[:, None]), axis=1)
    columns = ints.T.tolist() + reals.T.tolist() + flags.T.tolist()
    names = [""] * len(ident)
    for i in np.flatnonzero(emergency).tolist():
        names[i] = EMERGENCY_CODES[columns[_column("codes", MODE_3A)][i]]
    packed = ints[:, _column("codes", CALLSIGN)]
    callsign = np.full(len(ident), "", dtype="<U8")
    callsign[packed >= 0] = unpack_callsigns(packed[packed >= 0])
    columns += [names, callsign.tolist()]
    return present[:, _HAS], [columns[j] for j in _VALUE]


def track_rows(cols: dict[str, list], ident: TrackIdentity | None) -> list[dict]:
    """The Track JSON objects of the rows whose kinematic fields are ``cols`` (field →
    n values), with the identity fields their tracks have (:data:`FIELDS` order): one
    ``dict(zip())`` per row, by the row's pattern of fields."""
    keys = tuple(cols)
    if ident is None or len(ident) == 0:
        return [dict(zip(keys, r)) for r in zip(*cols.values())]
    has, values = identity_fields(ident)
    patterns = (has.astype(np.int64) @ _BITS).tolist()
    make = {p: _row_maker(keys, p) for p in set(patterns)}
    return [make[p](r) for p, r in zip(patterns, zip(*cols.values(), *values))]


@lru_cache(maxsize=4096)
def _row_maker(keys: tuple[str, ...], pattern: int) -> Callable[[tuple], dict]:
    """A row from the tuple (kinematic values, every field's value): the kinematic fields
    and the identity fields of ``pattern`` (a bit per field of :data:`FIELDS`)."""
    fields = [f for f in range(len(FIELDS)) if pattern >> f & 1]
    names = (*keys, *(FIELDS[f] for f in fields))
    pick = itemgetter(*range(len(keys)), *(len(keys) + f for f in fields))
    return lambda row: dict(zip(names, pick(row)))
