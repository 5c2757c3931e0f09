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

from operator import itemgetter

import numpy as np
from skyfuse.fusion.tracker.identity import (
    CALLSIGN,
    CODE_NAMES,
    DOWNLINK_NAMES,
    MODE_3A,
    REGISTER_COLUMNS,
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
_DOWNLINK_FIELDS = [FIELDS.index(name) for name in DOWNLINK_NAMES]
_REGISTER_FIELDS = [FIELDS.index(name) for name in REGISTER_TIMES]
_REGISTER_OF = np.zeros(len(DOWNLINK_NAMES), np.int64)
for _r, _cols in enumerate(REGISTER_COLUMNS):
    _REGISTER_OF[_cols] = _r


def identity_fields(ident: TrackIdentity) -> tuple[np.ndarray, list[list]]:
    """(n, :data:`FIELDS`) bool: which rows have which field, and each field's values
    (plain lists of n; a value where a row lacks the field is never read)."""
    n = len(ident)
    has = np.empty((n, len(FIELDS)), bool)
    shown = ident.codes >= 0
    has[:, 0:6:2] = has[:, 1:6:2] = shown
    mode_3a = ident.codes[:, MODE_3A]
    emergency = is_emergency(mode_3a)
    level = np.isfinite(ident.flight_level)
    has[:, 6:11] = np.stack((ident.mode_3a_changed, emergency, ident.spi, level, level), 1)
    reported = ident.downlink_time >= 0
    has[:, _DOWNLINK_FIELDS] = np.isfinite(ident.downlink) & reported[:, _REGISTER_OF]
    has[:, _REGISTER_FIELDS] = reported
    has[:, -2:] = ident.reply_time >= 0
    codes, times = ident.codes.T.tolist(), ident.code_time.T.tolist()
    callsign = np.full(n, "", dtype="<U8")
    callsign[shown[:, CALLSIGN]] = unpack_callsigns(ident.codes[shown[:, CALLSIGN], CALLSIGN])
    codes[CALLSIGN] = callsign.tolist()
    names = np.full(n, "", dtype=object)
    names[emergency] = [EMERGENCY_CODES[c] for c in mode_3a[emergency].tolist()]
    values = [v for k in range(len(CODE_NAMES)) for v in (codes[k], times[k])]
    values += [ident.mode_3a_changed.tolist(), names.tolist(), ident.spi.tolist(),
               ident.flight_level.tolist(), ident.flight_level_time.tolist()]  # fmt: skip
    downlink, registers = ident.downlink.T.tolist(), ident.downlink_time.T.tolist()
    for r, cols in enumerate(REGISTER_COLUMNS):
        values += [downlink[j] for j in cols] + [registers[r]]
    return has, values + ident.reply_time.T.tolist()


def track_rows(cols: dict[str, list], ident: TrackIdentity | None) -> list[dict]:
    """The Track JSON objects of the rows whose kinematic fields are ``cols`` (field →
    n values), with the identity fields their tracks have (:data:`FIELDS` order). The
    rows are built by which identity fields they have: one ``dict(zip())`` per row."""
    keys = list(cols)
    if ident is None or len(ident) == 0:
        return [dict(zip(keys, r)) for r in zip(*cols.values())]
    has, values = identity_fields(ident)
    pattern = has.astype(np.int64) @ _BITS
    _, first, kind, count = np.unique(pattern, return_index=True, return_inverse=True,
                                      return_counts=True)  # fmt: skip
    groups = np.split(np.argsort(kind, kind="stable"), np.cumsum(count)[:-1])
    full = list(zip(*cols.values(), *values))
    out: list[dict] = [{}] * len(full)
    base = range(len(keys))
    for present, rows in zip(has[first], groups):
        fields = np.flatnonzero(present).tolist()
        names = keys + [FIELDS[f] for f in fields]
        pick = itemgetter(*base, *(len(keys) + f for f in fields))
        for i in rows.tolist():
            out[i] = dict(zip(names, pick(full[i])))
    return out
