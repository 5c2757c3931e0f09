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

import numpy as np
from skyfuse.fusion.tracker.identity import (
    CALLSIGN,
    CODE_NAMES,
    DOWNLINK_NAMES,
    EMERGENCY,
    MODE_3A,
    MODE_S_REPLY,
    REGISTER_COLUMNS,
    SSR,
    TrackIdentity,
    unpack_callsigns,
)
from skyfuse.schemas.identity import EMERGENCY_CODES

REGISTER_TIMES = ("intention_time", "track_turn_time", "heading_speed_time")
"""The ``Track`` field of each register's time (BDS 4,0, 5,0, 6,0)."""


def identity_fields(ident: TrackIdentity) -> list[tuple[str, list[int], list]]:
    """(field, row indices, values) of every identity field that some row has; a row
    not among a field's indices does not have it."""
    out: list[tuple[str, list[int], list]] = []

    def add(name: str, mask: np.ndarray, values) -> None:
        idx = np.flatnonzero(mask)
        if len(idx):
            out.append((name, idx.tolist(), np.asarray(values)[idx].tolist()))

    for k, name in enumerate(CODE_NAMES):
        has = ident.codes[:, k] >= 0
        if not has.any():
            continue
        values = ident.codes[:, k]
        if k == CALLSIGN:
            values = np.full(len(has), "", dtype="<U8")
            values[has] = unpack_callsigns(ident.codes[has, k])
        add(name, has, values)
        add(f"{name}_time", has, ident.code_time[:, k])
    add("mode_3a_changed", ident.mode_3a_changed, ident.mode_3a_changed)
    code = ident.codes[:, MODE_3A]
    emergency = np.isin(code, EMERGENCY)
    if emergency.any():
        idx = np.flatnonzero(emergency)
        out.append(("emergency", idx.tolist(), [EMERGENCY_CODES[c] for c in code[idx].tolist()]))
    add("spi", ident.spi, ident.spi)
    level = np.isfinite(ident.flight_level)
    add("flight_level", level, ident.flight_level)
    add("flight_level_time", level, ident.flight_level_time)
    for r, cols in enumerate(REGISTER_COLUMNS):
        reported = ident.downlink_time[:, r] >= 0
        if not reported.any():
            continue
        for j in cols:
            add(
                DOWNLINK_NAMES[j],
                reported & np.isfinite(ident.downlink[:, j]),
                ident.downlink[:, j],
            )
        add(REGISTER_TIMES[r], reported, ident.downlink_time[:, r])
    add("ssr_time", ident.reply_time[:, SSR] >= 0, ident.reply_time[:, SSR])
    add("mode_s_update_time", ident.reply_time[:, MODE_S_REPLY] >= 0,
        ident.reply_time[:, MODE_S_REPLY])  # fmt: skip
    return out


def add_identity(rows: list[dict], ident: TrackIdentity | None) -> list[dict]:
    """The Track JSON objects ``rows`` with the identity fields of their tracks."""
    if ident is not None:
        for name, idx, values in identity_fields(ident):
            for i, v in zip(idx, values):
                rows[i][name] = v
    return rows
