"""Identity of the tracks: the secondary-surveillance attributes of the plots assigned to
them (docs/concepts/identity.md).

Every track shows, for each of its three **codes** — Mode-3/A code, Mode-S address,
callsign — the value the plots assigned to it replied with and the time a plot last
confirmed it; the **flight level** (Mode C, FL) of its last plot with a valid one and
that plot's time; the **SPI** of its last reply; the **downlinked parameters** of its
last plot that carried them (BDS 4,0 / 5,0 / 6,0, per register with that plot's time);
the times of its last update by a plot with an SSR (Mode A/C) reply and with a Mode S
reply. Names and units are the plot columns' (:mod:`schemas.identity`).

**Which plots.** A plot confirms a track's attributes when its association weight on
the track is above one half, β_i > 0.5 (the posterior probability that the plot is the
track's detection, [thesis] 5.17, 6.8: at most one plot of a batch per track), and it is
newer than the attribute's last confirmation (a late plot never overrides newer
evidence). The plot that started a track is its first sighting.

**Codes** (the same rule for the three, one (n, 3) array per column):

(I1) a plot *shows* a code when it carries one: a Mode-3/A code only when validated, not
     garbled and extracted in this scan (I048/070 V = G = L = 0); a Mode-S address or a
     callsign whenever present (parity-checked Mode S replies);
(I2) a shown code equal to the track's confirms it (its time) and drops the candidate;
(I3) a different code becomes the candidate; shown on ``confirm`` sightings in a row
     (none of the track's code between) it is adopted: it replaces the track's code.
     A garbled or unvalidated code is never seen, so it never replaces a validated one,
     and one stray reply never changes a track's identity.

**Flight level**: the plot's Mode C when validated and not garbled (I048/090 V = G = 0).

**Events** (:class:`~.events.TrackEventRecord`, counted in the step's stats and the
tracker's totals), for confirmed tracks:

* ``identity_changed``: an adopted code replaces another (a squawk change; a Mode-S
  address or a callsign replaced after their conflict);
* ``identity_conflict``: a Mode-S address or callsign other than the track's is shown
  within ``window`` of the last confirmation of the track's: one track holds two
  aircraft (a swap or a merge). At most one per attribute and track in a window;
* ``emergency``: the track's Mode-3/A code becomes 7500, 7600 or 7700;
* ``spi``: the special position identification is set where it was not.

A track confirmed while it shows an emergency code or SPI gets that event with its
``confirmed`` event. The Mode-3/A code counts as *changed* (CAT062 I062/060 CH) for
``hold`` after its change.

**Identity never drives association.** The tracker stays kinematic: no code enters a
gate, a likelihood or a track's existence, and attribution writes only its own columns.
So the states, ids and existence are those of a tracker without it, and scores that use
the Mode-S addresses as labels (the evaluation) do not grade the tracker on its own input.

Callsigns are packed into one int64 each: 8 characters of 6 bits, the ICAO 6-bit code of
BDS 2,0 (the low 6 bits of the ASCII code of ``A``-``Z``, ``0``-``9`` and space; padded
with spaces; −1: none), the I048/240 and I062/245 value.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from skyfuse.schemas.identity import DOWNLINK_REGISTERS, DOWNLINKED, EMERGENCY_CODES
from skyfuse.schemas.snapshot import array_field, mapping

from .events import TrackEventRecord
from .store import Column, ColumnGroup

MODE_3A, MODE_S, CALLSIGN = 0, 1, 2
CODE_NAMES = ("mode_3a", "mode_s", "callsign")
"""The codes, in the order of the (·, 3) columns."""
CODE_DESCRIPTIONS = ("Mode-3/A code", "Mode-S address", "callsign")
DOWNLINK_NAMES = tuple(q.name for q in DOWNLINKED)
"""The downlinked parameters, in the order of the (·, 12) columns."""
REGISTERS = tuple(DOWNLINK_REGISTERS)
"""The registers ("4,0", "5,0", "6,0"), in the order of the (·, 3) time columns."""
REGISTER_COLUMNS = tuple(
    np.array([DOWNLINK_NAMES.index(n) for n in DOWNLINK_REGISTERS[r]]) for r in REGISTERS
)
_IN_REGISTER = np.zeros((len(DOWNLINK_NAMES), len(REGISTERS)), bool)
for _r, _cols in enumerate(REGISTER_COLUMNS):
    _IN_REGISTER[_cols, _r] = True
SSR, MODE_S_REPLY = 0, 1
"""The reply kinds of the (·, 2) ``reply_time`` column."""
EMERGENCY = np.array(sorted(EMERGENCY_CODES), np.int64)
EVENT_COUNTERS = {"identity_changed": "identity_changes", "identity_conflict": "identity_conflicts",
                  "emergency": "emergencies", "spi": "spi_raised"}  # fmt: skip
"""The step stats (and tracker totals) counting each identity event kind."""
_SHIFTS = np.arange(42, -1, -6, dtype=np.int64)
_WEIGHTS = 1 << _SHIFTS
_SIX_BITS = np.full(129, -1, np.int64)
"""The 6-bit code of each character code (−1: not in the ICAO set; 0: padding, a space)."""
for _c in (0, 32, *range(48, 58), *range(65, 91)):
    _SIX_BITS[_c] = (32 if _c == 0 else _c) & 63
NONE = -1


# ---------------------------------------------------------------------------- callsigns
def pack_callsigns(text: np.ndarray) -> np.ndarray:
    """(m,) int64 packed callsigns of strings of at most 8 characters (``""``: −1), see
    the module docstring; a character outside the ICAO set also gives −1."""
    a = np.ascontiguousarray(text, dtype="<U8")
    m = len(a)
    if m == 0:
        return np.zeros(0, np.int64)
    six = _SIX_BITS[np.minimum(a.view(np.uint32).reshape(m, 8), 128)]
    return np.where((six >= 0).all(axis=1) & (a != ""), six @ _WEIGHTS, NONE)


def unpack_callsigns(packed: np.ndarray) -> np.ndarray:
    """(n,) strings (``<U8``, trailing spaces removed) of packed callsigns (≥ 0)."""
    p = np.asarray(packed, np.int64).reshape(-1)
    six = (p[:, None] >> _SHIFTS) & 63
    chars = np.where(six < 32, six | 64, six).astype(np.uint32)
    chars[np.logical_and.accumulate(chars[:, ::-1] == 32, axis=1)[:, ::-1]] = 0
    return np.ascontiguousarray(chars).view("<U8").ravel()


def is_emergency(mode_3a: np.ndarray) -> np.ndarray:
    """Whether each Mode-3/A code is an emergency code (7500, 7600, 7700)."""
    out = mode_3a == EMERGENCY[0]
    for code in EMERGENCY[1:]:
        out |= mode_3a == code
    return out


def code_text(attribute: int, code: int) -> str:
    """A code as text: Mode-3/A in octal, Mode-S address in hexadecimal, callsign."""
    if code < 0:
        return ""
    if attribute == MODE_3A:
        return f"{code:04o}"
    if attribute == MODE_S:
        return f"{code:06X}"
    return str(unpack_callsigns(np.array([code]))[0])


# ---------------------------------------------------------------------------- plots
@dataclass
class PlotIdentity:
    """The secondary-surveillance columns of a batch's m plots as the identity part
    reads them: ``codes`` (m, 3) int64 (Mode-3/A, Mode-S address, packed callsign; −1
    none), ``shown`` (m, 3) bool (the code counts as shown, (I1)), ``flight_level`` (m,)
    FL (NaN: none, or not validated or garbled), ``ssr`` (m,) bool (a Mode A/C reply: a
    code or a level, whatever their flags), ``spi`` (m,) bool, ``downlink`` (m, 12)
    (:data:`DOWNLINK_NAMES`, NaN none; None: no such column in the batch)."""

    codes: np.ndarray
    shown: np.ndarray
    flight_level: np.ndarray
    ssr: np.ndarray
    spi: np.ndarray
    downlink: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.codes)

    def take(self, idx: np.ndarray) -> PlotIdentity:
        """The plots ``idx`` (indices or a mask)."""
        return PlotIdentity(*(None if v is None else v[idx] for v in _values(self)))


def _values(obj) -> list:
    return list(obj.__dict__.values())  # the dataclass's fields, in their order


def plot_identity(column: Callable[[str], np.ndarray | None]) -> PlotIdentity | None:
    """The :class:`PlotIdentity` of a batch whose columns ``column(name)`` gives (e.g.
    ``PlotBatch.column``: arrays, −1 / NaN / False / "" for null; None for an absent
    column); None when it has no Mode-3/A, Mode-S, callsign or flight level column."""
    a3, s, cs, fl = (column(k) for k in ("mode_3a", "mode_s", "callsign", "flight_level"))
    present = [c for c in (a3, s, cs, fl) if c is not None]
    if not present:
        return None
    m = len(present[0])
    codes = np.full((m, 3), NONE, np.int64)
    for k, c in ((MODE_3A, a3), (MODE_S, s)):
        if c is not None:
            codes[:, k] = c
    if cs is not None:
        codes[:, CALLSIGN] = pack_callsigns(cs)
    shown = codes >= 0
    for flag in ("mode_3a_not_validated", "mode_3a_garbled", "mode_3a_smoothed"):
        f = column(flag)
        if f is not None:
            shown[:, MODE_3A] &= ~f
    level = np.full(m, np.nan) if fl is None else np.array(fl, dtype=np.float64)
    ssr = shown[:, MODE_3A] | (codes[:, MODE_3A] >= 0) | np.isfinite(level)
    for flag in ("flight_level_not_validated", "flight_level_garbled"):
        f = column(flag)
        if f is not None:
            level[f] = np.nan
    spi = column("spi")
    spi = np.zeros(m, bool) if spi is None else np.asarray(spi, bool)
    dl = [column(n) for n in DOWNLINK_NAMES]
    downlink = None
    if any(c is not None for c in dl):
        downlink = np.full((m, len(dl)), np.nan)
        for j, c in enumerate(dl):
            if c is not None:
                downlink[:, j] = c
    return PlotIdentity(codes, shown, level, ssr, spi, downlink)


# ---------------------------------------------------------------------------- tracks
BLOCKS = {"ints": np.int64, "reals": np.float64, "flags": np.bool_}
LAYOUT = {
    "codes": ("ints", slice(0, 3)), "code_time": ("ints", slice(3, 6)),
    "mode_3a_changed": ("flags", 0), "flight_level": ("reals", 0),
    "flight_level_time": ("ints", 6), "spi": ("flags", 1),
    "downlink": ("reals", slice(1, 1 + len(DOWNLINK_NAMES))),
    "downlink_time": ("ints", slice(7, 7 + len(REGISTERS))),
    "reply_time": ("ints", slice(10, 12)), "revision": ("ints", 12),
}  # fmt: skip
"""Each field of :class:`TrackIdentity`: its block and columns there."""
BLOCK_WIDTH = {"ints": 13, "reals": 1 + len(DOWNLINK_NAMES), "flags": 2}
_FILL = {"ints": NONE, "reals": np.nan, "flags": False}


class TrackIdentity:
    """The identity of n tracks (copies of the store's columns, :class:`Identity`):
    ``codes`` (n, 3) and ``code_time`` (n, 3) ns (−1: none), ``mode_3a_changed`` (n,)
    bool (changed within ``hold``), ``flight_level`` (n,) FL (NaN: none) and its time,
    ``spi`` (n,), ``downlink`` (n, 12) with ``downlink_time`` (n, 3) per register,
    ``reply_time`` (n, 2): last update by a plot with an SSR / a Mode S reply;
    ``revision`` (n,): +1 at every change of what a track shows (a published row moves).
    Held in three blocks (``ints`` (n, 13), ``reals`` (n, 13), ``flags`` (n, 2),
    :data:`LAYOUT`), the fields views of them: taking or joining rows (the feed's
    tables) is three copies."""

    __slots__ = tuple(BLOCKS)

    def __init__(self, ints: np.ndarray, reals: np.ndarray, flags: np.ndarray) -> None:
        self.ints, self.reals, self.flags = ints, reals, flags

    @classmethod
    def of(cls, **fields_: np.ndarray) -> TrackIdentity:
        """From every field of :data:`LAYOUT` by name (arrays of n rows)."""
        n = len(fields_["codes"])
        blocks = {k: np.empty((n, BLOCK_WIDTH[k]), dt) for k, dt in BLOCKS.items()}
        for name, (block, cols) in LAYOUT.items():
            blocks[block][:, cols] = fields_[name]
        return cls(**blocks)

    def __len__(self) -> int:
        return len(self.ints)

    def take(self, idx: np.ndarray) -> TrackIdentity:
        return TrackIdentity(self.ints[idx], self.reals[idx], self.flags[idx])

    @classmethod
    def none(cls, n: int) -> TrackIdentity:
        """n tracks without identity."""
        return cls(*(np.full((n, BLOCK_WIDTH[k]), _FILL[k], dt) for k, dt in BLOCKS.items()))

    @staticmethod
    def concat(parts: list[TrackIdentity]) -> TrackIdentity:
        return TrackIdentity(*(np.concatenate([getattr(p, k) for p in parts]) for k in BLOCKS))

    def to_snapshot(self) -> dict:
        return {name: np.ascontiguousarray(getattr(self, name)) for name in LAYOUT}

    @classmethod
    def from_snapshot(cls, snap, n: int) -> TrackIdentity:
        """Read :meth:`to_snapshot` of n tracks (``SnapshotError`` if it does not fit)."""
        snap, ref = mapping(snap, "track identity"), cls.none(n)
        like = {name: getattr(ref, name) for name in LAYOUT}
        return cls.of(**{k: array_field(snap, k, v.dtype, v.shape) for k, v in like.items()})


for _name, (_block, _cols) in LAYOUT.items():
    setattr(TrackIdentity, _name, property(lambda self, b=_block, c=_cols: getattr(self, b)[:, c]))


def identity_columns() -> ColumnGroup:
    """The identity part's columns of the track store (see :class:`Identity`)."""
    i8, f8 = np.int64, np.float64
    return ColumnGroup(
        "identity",
        (Column("ident_code", i8, (3,), fill=NONE, doc="Mode-3/A, Mode-S, callsign shown"),
         Column("ident_time", i8, (3,), fill=NONE, doc="time each was last confirmed, ns"),
         Column("ident_cand", i8, (3,), fill=NONE, doc="candidate codes (I3)"),
         Column("ident_seen", i8, (3,), fill=0, doc="sightings in a row of the candidate"),
         Column("ident_changed", i8, (3,), fill=NONE, doc="time of the last change, ns"),
         Column("ident_conflict", i8, (3,), fill=NONE, doc="time of the last conflict, ns"),
         Column("flight_level", f8, fill=np.nan, doc="Mode C of the last valid plot, FL"),
         Column("flight_level_time", i8, fill=NONE, doc="its time, ns"),
         Column("spi", bool, fill=False, doc="SPI of the last reply"),
         Column("downlink", f8, (len(DOWNLINK_NAMES),), fill=np.nan, doc="BDS 4,0/5,0/6,0"),
         Column("downlink_time", i8, (len(REGISTERS),), fill=NONE, doc="per register, ns"),
         Column("reply_time", i8, (2,), fill=NONE, doc="last SSR / Mode S update, ns"),
         Column("ident_revision", i8, fill=0, doc="+1 at every change of the above")),
    )  # fmt: skip


class Identity:
    """The identity part of a tracker (see the module docstring): its columns of the
    track store ``tracks``, the rules (I1)-(I3), the events. ``cfg``: the
    ``TrackerConfig`` (``identity_confirm``, ``identity_conflict_window``,
    ``identity_change_hold``); ``chain``: the existence chain (the events' ψ)."""

    def __init__(self, cfg, tracks, chain) -> None:
        self.tracks, self.chain = tracks, chain
        self.confirm = int(cfg.identity_confirm)
        self.window = round(cfg.identity_conflict_window * 1e9)
        self.hold = round(cfg.identity_change_hold * 1e9)
        self.pending: list[TrackEventRecord] = []
        """Events of the current step, until :meth:`flush` (never kept across steps)."""
        self.counts: dict[str, int] = {}
        tracks.declare(identity_columns())

    # ------------------------------------------------------------------ observation
    def observe(self, pid: PlotIdentity | None, rows: np.ndarray, plots: np.ndarray,
                t: np.ndarray) -> None:  # fmt: skip
        """Tracks ``rows`` (distinct) each confirmed by plot ``plots`` of a batch whose
        identity is ``pid``, at the plots' times ``t`` (ns)."""
        if pid is None or len(rows) == 0:
            return
        t = np.asarray(t, np.int64)
        obs = pid.codes[plots]
        touched = self._codes(pid, rows, plots, t, obs)
        touched |= self._level_and_replies(pid, rows, plots, t, obs)
        if pid.downlink is not None:
            touched |= self._downlink(pid.downlink[plots], rows, t)
        self.tracks.ident_revision[rows[touched]] += 1

    def _codes(self, pid, rows, plots, t, obs) -> np.ndarray:
        """(I1)-(I3) and their events for the three codes at once; returns the rows
        whose codes or times changed."""
        tr, tt = self.tracks, t[:, None]
        shown, t_shown = tr.ident_code[rows], tr.ident_time[rows]
        cand, count = tr.ident_cand[rows], tr.ident_seen[rows]
        seen = pid.shown[plots] & (tt > t_shown)
        same = seen & (obs == shown)
        other = seen & ~same
        if not other.any():  # the usual step: the plots confirm the tracks' codes
            return self._confirmed_codes(rows, tt, same, t_shown, cand, count)
        count = np.where(
            same, 0, np.where(other & (obs == cand), count + 1, np.where(other, 1, count))
        )
        cand = np.where(same, NONE, np.where(other, obs, cand))
        adopt = other & (count >= self.confirm)
        conflict = other & (shown >= 0) & (tt - t_shown <= self.window)
        conflict &= tt - tr.ident_conflict[rows] > self.window
        conflict[:, MODE_3A] = False  # a new squawk is a change, not a second aircraft
        new = np.where(adopt, cand, shown)
        tr.ident_code[rows] = new
        tr.ident_time[rows] = np.where(same | adopt, tt, t_shown)
        tr.ident_cand[rows] = np.where(adopt, NONE, cand)
        tr.ident_seen[rows] = np.where(adopt, 0, count)
        changed = adopt & (shown >= 0)
        tr.ident_changed[rows] = np.where(changed, tt, tr.ident_changed[rows])
        tr.ident_conflict[rows] = np.where(conflict, tt, tr.ident_conflict[rows])
        if changed.any() or conflict.any() or adopt[:, MODE_3A].any():
            was = is_emergency(shown[:, MODE_3A])
            emergency = adopt[:, MODE_3A] & is_emergency(new[:, MODE_3A]) & ~was
            conf = tr.confirmed[rows]
            self._code_events(rows, t, conf, obs, shown, new, changed, conflict, emergency)
        return (same | adopt).any(axis=1)

    def _confirmed_codes(self, rows, tt, same, t_shown, cand, count) -> np.ndarray:
        """:meth:`_codes` when every shown code equals the track's, (I2): their times,
        and no candidate left where one was."""
        tr = self.tracks
        tr.ident_time[rows] = np.where(same, tt, t_shown)
        stale = same & ((cand != NONE) | (count != 0))
        if stale.any():
            tr.ident_cand[rows] = np.where(stale, NONE, cand)
            tr.ident_seen[rows] = np.where(stale, 0, count)
        return same.any(axis=1)

    def _code_events(self, rows, t, conf, obs, shown, new, changed, conflict, emergency):
        """The events of :meth:`_codes` for the confirmed tracks among ``rows``."""
        window = f"{self.window * 1e-9:g} s"
        for i, k in zip(*np.nonzero(conflict & conf[:, None])):
            why = f"{CODE_DESCRIPTIONS[k]} other than the track's within {window}: two aircraft"
            seen, had = code_text(k, obs[i, k]), code_text(k, shown[i, k])
            self._event(rows[i], t[i], "identity_conflict", CODE_NAMES[k], seen, had, why)
        for i, k in zip(*np.nonzero(changed & conf[:, None])):
            now, had = code_text(k, new[i, k]), code_text(k, shown[i, k])
            why = f"{CODE_DESCRIPTIONS[k]} changed"
            self._event(rows[i], t[i], "identity_changed", CODE_NAMES[k], now, had, why)
        for i in np.flatnonzero(emergency & conf):
            self._emergency(rows[i], t[i], new[i, MODE_3A])

    def _level_and_replies(self, pid, rows, plots, t, obs) -> np.ndarray:
        """Flight level, the reply times and SPI (set by every reply newer than the
        track's last one); returns the rows whose level or reply times changed."""
        tr, tt = self.tracks, t[:, None]
        fl = pid.flight_level[plots]
        ok = np.isfinite(fl) & (t > tr.flight_level_time[rows])
        if ok.any():
            r = rows[ok]
            tr.flight_level[r], tr.flight_level_time[r] = fl[ok], t[ok]
        kinds = np.stack((pid.ssr[plots], obs[:, MODE_S] >= 0), axis=1)  # SSR, MODE_S_REPLY
        last = tr.reply_time[rows]
        newer = kinds & (tt > last)
        tr.reply_time[rows] = np.where(newer, tt, last)
        reply = kinds.any(axis=1) & (t > last.max(axis=1))
        if reply.any():
            r = rows[reply]
            before, after = tr.spi[r], pid.spi[plots[reply]]
            tr.spi[r] = after
            for i in np.flatnonzero(after & ~before & tr.confirmed[r]):
                self._spi(r[i], t[reply][i])
        return ok | newer.any(axis=1)

    def _downlink(self, dl: np.ndarray, rows: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Each register's parameters of the plots that carry any of them; returns the
        rows that took some."""
        tr, tt = self.tracks, t[:, None]
        last = tr.downlink_time[rows]
        take = (np.isfinite(dl) @ _IN_REGISTER) & (tt > last)
        if take.any():
            tr.downlink[rows] = np.where(take @ _IN_REGISTER.T, dl, tr.downlink[rows])
            tr.downlink_time[rows] = np.where(take, tt, last)
        return take.any(axis=1)

    # ------------------------------------------------------------------ events
    def _event(self, row, t, kind, attribute, value="", previous="", reason="") -> None:
        tr = self.tracks
        psi = float(self.chain.existence(tr.exist[row : row + 1])[0])
        self.pending.append(TrackEventRecord(int(t), kind, int(tr.ids[row]), psi,
                                             reason=reason, attribute=attribute, value=value,
                                             previous=previous))  # fmt: skip
        self.counts[kind] = self.counts.get(kind, 0) + 1

    def _emergency(self, row, t, code) -> None:
        name = EMERGENCY_CODES[int(code)].replace("_", " ")
        self._event(row, t, "emergency", "mode_3a", code_text(MODE_3A, code),
                    reason=f"Mode-3/A {code_text(MODE_3A, code)}: {name}")  # fmt: skip

    def _spi(self, row, t) -> None:
        self._event(row, t, "spi", "spi", reason="special position identification")

    def confirmed(self, rows: np.ndarray, t_batch: int) -> None:
        """Tracks ``rows`` confirmed now: the emergency and SPI they already show."""
        tr = self.tracks
        for r in rows[is_emergency(tr.ident_code[rows, MODE_3A])]:
            self._emergency(r, t_batch, tr.ident_code[r, MODE_3A])
        for r in rows[tr.spi[rows]]:
            self._spi(r, t_batch)

    def flush(self, events: list, stats: dict[str, int]) -> None:
        """Move the step's events into ``events`` and their counts into ``stats``
        (:data:`EVENT_COUNTERS`; only the kinds that occurred)."""
        events += self.pending
        for kind, n in self.counts.items():
            stats[EVENT_COUNTERS[kind]] = n
        self.pending, self.counts = [], {}

    # ------------------------------------------------------------------ output
    def output(self, time_ns: int) -> TrackIdentity:
        """Copies of every track's identity at ``time_ns`` (the newest batch time)."""
        tr = self.tracks
        changed = tr.ident_changed[:, MODE_3A]
        return TrackIdentity.of(
            codes=tr.ident_code,
            code_time=tr.ident_time,
            mode_3a_changed=(changed >= 0) & (time_ns - changed <= self.hold),
            flight_level=tr.flight_level,
            flight_level_time=tr.flight_level_time,
            spi=tr.spi,
            downlink=tr.downlink,
            downlink_time=tr.downlink_time,
            reply_time=tr.reply_time,
            revision=tr.ident_revision,
        )
