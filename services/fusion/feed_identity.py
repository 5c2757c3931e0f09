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
"""

from __future__ import annotations

from operator import itemgetter

import numpy as np
from skyfuse.fusion.tracker.identity import (
    CALLSIGN,
    CODE_NAMES,
    DOWNLINK_NAMES,
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
    "ssr_time", "mode_s_update_time",
)  # fmt: skip
"""The identity fields of a ``Track`` row, in the order a row lists those it has."""
_BITS = 1 << np.arange(len(FIELDS), dtype=np.int64)


def identity_fields(ident: TrackIdentity) -> tuple[np.ndarray, list[list]]:
    """(n, :data:`FIELDS`) bool: which rows have which field, and each field's values
    (plain lists of n; a value where a row lacks the field is never read)."""
    n = len(ident)
    has, values = [], []
    for k in range(len(CODE_NAMES)):
        code = ident.codes[:, k]
        has += [code >= 0] * 2
        values += [code, ident.code_time[:, k]]
    shown = has[2 * CALLSIGN]
    callsign = np.full(n, "", dtype="<U8")
    if shown.any():
        callsign[shown] = unpack_callsigns(ident.codes[shown, CALLSIGN])
    values[2 * CALLSIGN] = callsign
    code = ident.codes[:, MODE_3A]
    emergency = is_emergency(code)
    names = np.full(n, "", dtype=object)
    names[emergency] = [EMERGENCY_CODES[c] for c in code[emergency].tolist()]
    level = np.isfinite(ident.flight_level)
    has += [ident.mode_3a_changed, emergency, ident.spi, level, level]
    values += [ident.mode_3a_changed, names, ident.spi, ident.flight_level,
               ident.flight_level_time]  # fmt: skip
    for r, cols in enumerate(REGISTER_COLUMNS):
        reported = ident.downlink_time[:, r] >= 0
        has += [reported & np.isfinite(ident.downlink[:, j]) for j in cols] + [reported]
        values += [ident.downlink[:, j] for j in cols] + [ident.downlink_time[:, r]]
    for k in (SSR, MODE_S_REPLY):
        has.append(ident.reply_time[:, k] >= 0)
        values.append(ident.reply_time[:, k])
    return np.stack(has, axis=1), [v.tolist() for v in values]


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
