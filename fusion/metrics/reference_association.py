"""Which reference aircraft each track update belongs to, for scoring tracks against an
independent reference (ADS-B or multilateration positions with aircraft addresses).

Inputs are two sets of arrays in one east/north plane (m):

* :class:`TrackUpdates` — one row per update of a published (confirmed) track: time,
  track id, position, and optionally the identity the track shows (Mode-S address,
  callsign, Mode-3/A) and a ground flag.
* :class:`ReferenceSamples` — one row per reference report: time, aircraft key (the
  24-bit address), position, ground/airborne flag, optionally the report's own σ (m per
  axis), callsign and Mode-3/A.

**The reference between its samples.** An aircraft's position at time t is the linear
interpolation of its two samples around t, when they are at most ``max_gap_s`` apart
(never extrapolated; no position across a longer gap). Its phase (ground / airborne) and
σ are those of the nearer of the two samples, its velocity the difference of the two
positions over their time difference. The reference is *present* over *segments*: runs
of consecutive samples of one phase whose gaps are at most ``max_gap_s``.

**Association rule** (written for this project; the published evaluation tools
associate by address or by a distance to the interpolated reference as well — COMPASS
user manual, ASTMOPS; see docs/evaluation-reference.md):

1. *Label.* Each update gets the nearest reference aircraft whose interpolated position
   at the update time is within the gate of that aircraft's phase (``gate_surface_m``,
   ``gate_airborne_m``); −1 when none is. Several tracks may get the same aircraft.
2. *Majority.* Along each track, an update is assigned the label that is most frequent
   among the labels of the same track's updates within ±``majority_window_s``/2 of it
   ("no aircraft", −1, counts as a label). Ties go to an aircraft over −1, then to the
   aircraft with the smaller mean distance in the window. A track that crosses another
   aircraft for a moment keeps its aircraft; a track that leaves its aircraft loses it
   within half a window.
3. *Credited.* An update assigned to an aircraft is credited to it when the reference
   gives that aircraft a position at the update time; its position error is the update
   minus that position (which may exceed the gate: the majority says whose track it is).

The rule never uses the identity a track shows: identity is scored, not used.
Times: ns (int64) in, seconds after a common epoch inside (float64).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

NO_AIRCRAFT = -1
UNKNOWN = -1
AIRBORNE, GROUND = 0, 1


def _column(name: str, a, n: int, dtype, fill=None) -> np.ndarray:
    """``a`` as an (n,) array of ``dtype``; ``fill`` everywhere when ``a`` is None."""
    if a is None:
        return np.full(n, fill, dtype=dtype)
    a = np.asarray(a)
    if a.shape != (n,):
        raise ValueError(f"{name}: shape {a.shape}: must be ({n},)")
    return a.astype(dtype, copy=False)


def _times(name: str, t) -> np.ndarray:
    t = np.asarray(t)
    if t.ndim != 1 or not (np.issubdtype(t.dtype, np.integer) or t.size == 0):
        raise ValueError(f"{name}: shape {t.shape}, dtype {t.dtype}: must be (n,) integer ns")
    return t.astype(np.int64)


def _finite(name: str, a, n: int) -> np.ndarray:
    a = _column(name, a, n, np.float64)
    if not np.isfinite(a).all():
        raise ValueError(f"{name}: row {int(np.flatnonzero(~np.isfinite(a))[0])} is not finite")
    return a


@dataclass(frozen=True)
class TrackUpdates:
    """Updates of published tracks: ``time_ns`` (n,) int64, ``track_id`` (n,) int64 ≥ 0,
    ``x``, ``y`` (n,) m east/north; optional ``mode_s`` (n,) int64 (−1 unknown),
    ``callsign`` (n,) object (None unknown), ``mode_3a`` (n,) int64 (−1 unknown),
    ``ground`` (n,) int8 (1 ground, 0 airborne, −1 unknown)."""

    time_ns: np.ndarray
    track_id: np.ndarray
    x: np.ndarray
    y: np.ndarray
    mode_s: np.ndarray | None = None
    callsign: np.ndarray | None = None
    mode_3a: np.ndarray | None = None
    ground: np.ndarray | None = None

    def __post_init__(self) -> None:
        t = _times("time_ns", self.time_ns)
        n = len(t)
        trk = _column("track_id", self.track_id, n, np.int64)
        if n and trk.min() < 0:
            raise ValueError(f"track_id: value {int(trk.min())}: must be >= 0")
        cols = {
            "time_ns": t,
            "track_id": trk,
            "x": _finite("x", self.x, n),
            "y": _finite("y", self.y, n),
            "mode_s": _column("mode_s", self.mode_s, n, np.int64, -1),
            "callsign": _column("callsign", self.callsign, n, object, None),
            "mode_3a": _column("mode_3a", self.mode_3a, n, np.int64, -1),
            "ground": _column("ground", self.ground, n, np.int8, UNKNOWN),
        }
        for k, v in cols.items():
            object.__setattr__(self, k, v)

    def __len__(self) -> int:
        return len(self.time_ns)

    def take(self, rows) -> TrackUpdates:
        """The updates ``rows`` (indices or a boolean mask)."""
        return TrackUpdates(*(getattr(self, k)[rows] for k in _UPDATE_FIELDS))

    @classmethod
    def concat(cls, parts: list[TrackUpdates]) -> TrackUpdates:
        if not parts:
            z = np.zeros(0, np.int64)
            return cls(z, z, np.zeros(0), np.zeros(0))
        return cls(*(np.concatenate([getattr(p, k) for p in parts]) for k in _UPDATE_FIELDS))


@dataclass(frozen=True)
class ReferenceSamples:
    """Reference reports: ``time_ns`` (m,) int64, ``key`` (m,) int64 aircraft (address),
    ``x``, ``y`` (m,) m east/north, ``ground`` (m,) bool; optional ``sigma`` (m,) m per
    axis (NaN unknown), ``callsign`` (m,) object, ``mode_3a`` (m,) int64 (−1 unknown)."""

    time_ns: np.ndarray
    key: np.ndarray
    x: np.ndarray
    y: np.ndarray
    ground: np.ndarray
    sigma: np.ndarray | None = None
    callsign: np.ndarray | None = None
    mode_3a: np.ndarray | None = None

    def __post_init__(self) -> None:
        t = _times("time_ns", self.time_ns)
        n = len(t)
        cols = {
            "time_ns": t,
            "key": _column("key", self.key, n, np.int64),
            "x": _finite("x", self.x, n),
            "y": _finite("y", self.y, n),
            "ground": _column("ground", self.ground, n, bool),
            "sigma": _column("sigma", self.sigma, n, np.float64, np.nan),
            "callsign": _column("callsign", self.callsign, n, object, None),
            "mode_3a": _column("mode_3a", self.mode_3a, n, np.int64, -1),
        }
        for k, v in cols.items():
            object.__setattr__(self, k, v)

    def __len__(self) -> int:
        return len(self.time_ns)

    def take(self, rows) -> ReferenceSamples:
        """The samples ``rows`` (indices or a boolean mask)."""
        return ReferenceSamples(*(getattr(self, k)[rows] for k in _SAMPLE_FIELDS))

    def shifted(self, seconds: float) -> ReferenceSamples:
        """The same samples with ``seconds`` added to every time stamp."""
        dt = np.int64(round(seconds * 1e9))
        cols = [getattr(self, k) for k in _SAMPLE_FIELDS]
        return ReferenceSamples(self.time_ns + dt, *cols[1:])


_UPDATE_FIELDS = ("time_ns", "track_id", "x", "y", "mode_s", "callsign", "mode_3a", "ground")
_SAMPLE_FIELDS = ("time_ns", "key", "x", "y", "ground", "sigma", "callsign", "mode_3a")


@dataclass(frozen=True)
class ReferencePoint:
    """The reference of one aircraft at given times (arrays over those times): position
    ``x``, ``y``, whether it is ``valid`` (bracketed by samples ≤ max gap apart),
    ``ground``, ``sigma``, velocity ``vx``, ``vy`` (NaN where two samples share a time)."""

    x: np.ndarray
    y: np.ndarray
    valid: np.ndarray
    ground: np.ndarray
    sigma: np.ndarray
    vx: np.ndarray
    vy: np.ndarray


@dataclass
class ReferenceIndex:
    """The reference sorted by aircraft then time, with per-aircraft slices and presence
    segments (module docstring). ``t`` in s after ``epoch_ns``. Aircraft with fewer than
    ``min_samples`` samples are left out (``dropped_aircraft``)."""

    keys: np.ndarray
    start: np.ndarray
    stop: np.ndarray
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    ground: np.ndarray
    sigma: np.ndarray
    callsign: np.ndarray
    mode_3a: np.ndarray
    max_gap_s: float
    epoch_ns: int = 0
    dropped_aircraft: int = 0
    segments: list[np.ndarray] = field(default_factory=list)

    @classmethod
    def build(cls, ref: ReferenceSamples, epoch_ns: int, max_gap_s: float, min_samples: int):
        min_samples = max(int(min_samples), 2)  # interpolation needs two samples
        order = np.lexsort((ref.time_ns, ref.key))
        key = ref.key[order]
        keys, first, counts = np.unique(key, return_index=True, return_counts=True)
        keep = counts >= min_samples
        rows = np.concatenate(
            [np.arange(f, f + c) for f, c in zip(first[keep], counts[keep])] or [np.zeros(0, int)]
        ).astype(np.int64)
        sel = order[rows]
        stop = np.cumsum(counts[keep])
        idx = cls(
            keys=keys[keep], start=stop - counts[keep], stop=stop,
            t=(ref.time_ns[sel] - epoch_ns) * 1e-9, x=ref.x[sel], y=ref.y[sel],
            ground=ref.ground[sel], sigma=ref.sigma[sel], callsign=ref.callsign[sel],
            mode_3a=ref.mode_3a[sel], max_gap_s=max_gap_s, epoch_ns=int(epoch_ns),
            dropped_aircraft=int((~keep).sum()),
        )  # fmt: skip
        idx.segments = [idx._segments(a) for a in range(len(idx.keys))]
        return idx

    def __len__(self) -> int:
        return len(self.keys)

    def span(self, a: int) -> tuple[float, float]:
        return float(self.t[self.start[a]]), float(self.t[self.stop[a] - 1])

    def _segments(self, a: int) -> np.ndarray:
        """(k, 3) rows (start s, end s, ground 0/1) of the aircraft's presence segments."""
        sl = slice(self.start[a], self.stop[a])
        t, g = self.t[sl], self.ground[sl]
        cut = np.flatnonzero((np.diff(t) > self.max_gap_s) | (g[1:] != g[:-1]))
        first = np.r_[0, cut + 1]
        last = np.r_[cut, len(t) - 1]
        return np.column_stack([t[first], t[last], g[first].astype(float)])

    def at(self, a: int, t: np.ndarray) -> ReferencePoint:
        """Aircraft ``a`` at times ``t`` (s after the epoch; module docstring)."""
        lo, hi = self.start[a], self.stop[a]
        tt = self.t[lo:hi]
        k1 = np.clip(np.searchsorted(tt, t, side="left"), 1, len(tt) - 1) + lo
        k0 = k1 - 1
        dt = self.t[k1] - self.t[k0]
        valid = (t >= self.t[k0]) & (t <= self.t[k1]) & (dt <= self.max_gap_s)
        with np.errstate(invalid="ignore", divide="ignore"):
            w = np.where(dt > 0, (t - self.t[k0]) / np.where(dt > 0, dt, 1.0), 0.0)
            vx = np.where(dt > 0, (self.x[k1] - self.x[k0]) / dt, np.nan)
            vy = np.where(dt > 0, (self.y[k1] - self.y[k0]) / dt, np.nan)
        near = np.where(w < 0.5, k0, k1)
        return ReferencePoint(
            x=self.x[k0] + w * (self.x[k1] - self.x[k0]),
            y=self.y[k0] + w * (self.y[k1] - self.y[k0]),
            valid=valid, ground=self.ground[near], sigma=self.sigma[near], vx=vx, vy=vy,
        )  # fmt: skip

    def identity_at(self, a: int, t: np.ndarray, name: str) -> np.ndarray:
        """The aircraft's last reported ``callsign``/``mode_3a`` at or before each time
        (else its first one after), None / −1 when it never reports one."""
        lo, hi = self.start[a], self.stop[a]
        v = getattr(self, name)[lo:hi]
        known = np.flatnonzero(np.array([x is not None for x in v]) if name == "callsign"
                               else v >= 0)  # fmt: skip
        empty = None if name == "callsign" else -1
        out = np.full(len(t), empty, dtype=v.dtype)
        if not len(known):
            return out
        tk = self.t[lo:hi][known]
        j = np.clip(np.searchsorted(tk, t, side="right") - 1, 0, len(known) - 1)
        return v[known[j]]


@dataclass(frozen=True)
class Association:
    """Per update (in the order of the :class:`TrackUpdates` given): ``label`` (nearest
    aircraft within the gate, index into ``ReferenceIndex.keys``, −1 none), ``assigned``
    (after the majority rule), ``credited`` (assigned and the reference has a position),
    ``err_x``, ``err_y`` (update − reference, m; NaN when not credited), the reference's
    ``ground``, ``sigma``, ``vx``, ``vy`` at credited updates, and ``nearest_m``,
    ``nearest_ground`` (distance to and phase of the nearest aircraft the reference places
    at that time, any distance; inf / −1 when none)."""

    label: np.ndarray
    assigned: np.ndarray
    credited: np.ndarray
    err_x: np.ndarray
    err_y: np.ndarray
    ground: np.ndarray
    sigma: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    nearest_m: np.ndarray
    nearest_ground: np.ndarray


def nearest_labels(
    t: np.ndarray, x: np.ndarray, y: np.ndarray, ref: ReferenceIndex,
    gate_surface_m: float, gate_airborne_m: float, known_key: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Step 1 of the rule: (label, its distance m, nearest distance any aircraft m, that
    aircraft's ground flag) per update; ``t`` in s after the epoch. ``known_key`` (n,)
    (−1 unknown) is for the plots of the input bound only
    (:mod:`.reference_coverage`), never for track updates: a row whose address is known
    is labelled only to the aircraft of that address."""
    n = len(t)
    label = np.full(n, NO_AIRCRAFT, np.int64)
    best = np.full(n, np.inf)
    nearest = np.full(n, np.inf)
    nearest_ground = np.full(n, UNKNOWN, np.int8)
    by_time = np.argsort(t, kind="stable")
    ts = t[by_time]
    for a in range(len(ref)):
        t0, t1 = ref.span(a)
        idx = by_time[np.searchsorted(ts, t0, "left") : np.searchsorted(ts, t1, "right")]
        if not len(idx):
            continue
        p = ref.at(a, t[idx])
        d = np.hypot(x[idx] - p.x, y[idx] - p.y)
        d[~p.valid] = np.inf
        if known_key is not None:
            d[(known_key[idx] >= 0) & (known_key[idx] != ref.keys[a])] = np.inf
        closer = d < nearest[idx]
        nearest[idx[closer]] = d[closer]
        nearest_ground[idx[closer]] = p.ground[closer]
        gate = np.where(p.ground, gate_surface_m, gate_airborne_m)
        win = (d <= gate) & (d < best[idx])
        label[idx[win]] = a
        best[idx[win]] = d[win]
    return label, best, nearest, nearest_ground


def majority_labels(
    t: np.ndarray, track: np.ndarray, label: np.ndarray, dist: np.ndarray, window_s: float
) -> np.ndarray:
    """Step 2 of the rule: the windowed majority label of each update along its track."""
    out = np.full(len(t), NO_AIRCRAFT, np.int64)
    order = np.lexsort((t, track))
    ts, trk, lab = t[order], track[order], label[order]
    d = np.where(lab >= 0, dist[order], 0.0)
    cuts = np.flatnonzero(np.r_[True, trk[1:] != trk[:-1], True])
    half = 0.5 * window_s
    for lo, hi in itertools.pairwise(cuts):
        seg = lab[lo:hi]
        if (seg < 0).all():
            continue
        names, code = np.unique(seg, return_inverse=True)
        onehot = np.zeros((hi - lo, len(names)))
        onehot[np.arange(hi - lo), code] = 1.0
        zero = np.zeros((1, len(names)))
        c_count = np.vstack([zero, np.cumsum(onehot, axis=0)])
        c_dist = np.vstack([zero, np.cumsum(onehot * d[lo:hi, None], axis=0)])
        tt = ts[lo:hi]
        a = np.searchsorted(tt, tt - half, "left")
        b = np.searchsorted(tt, tt + half, "right")
        count = c_count[b] - c_count[a]
        with np.errstate(invalid="ignore", divide="ignore"):
            mean_d = (c_dist[b] - c_dist[a]) / count
        is_aircraft = names >= 0
        scale = np.nanmax(np.where(count > 0, mean_d, np.nan)) + 1.0
        bonus = np.where(is_aircraft, 0.25 - 0.25 * np.nan_to_num(mean_d) / scale, 0.0)
        score = np.where(count > 0, count + bonus, -1.0)
        out[order[lo:hi]] = names[np.argmax(score, axis=1)]
    return out


def associate(
    updates: TrackUpdates, ref: ReferenceIndex, epoch_ns: int, *,
    gate_surface_m: float, gate_airborne_m: float, majority_window_s: float,
) -> Association:  # fmt: skip
    """The three steps of the module docstring over all updates."""
    t = (updates.time_ns - epoch_ns) * 1e-9
    label, dist, nearest, nearest_ground = nearest_labels(
        t, updates.x, updates.y, ref, gate_surface_m, gate_airborne_m
    )
    assigned = majority_labels(t, updates.track_id, label, dist, majority_window_s)
    n = len(t)
    err_x, err_y, sigma, vx, vy = (np.full(n, np.nan) for _ in range(5))
    ground = np.zeros(n, bool)
    credited = np.zeros(n, bool)
    for a in np.unique(assigned[assigned >= 0]).tolist():
        idx = np.flatnonzero(assigned == a)
        p = ref.at(a, t[idx])
        ok = idx[p.valid]
        credited[ok] = True
        err_x[ok] = updates.x[ok] - p.x[p.valid]
        err_y[ok] = updates.y[ok] - p.y[p.valid]
        for arr, v in ((ground, p.ground), (sigma, p.sigma), (vx, p.vx), (vy, p.vy)):
            arr[ok] = v[p.valid]
    return Association(
        label, assigned, credited, err_x, err_y, ground, sigma, vx, vy, nearest, nearest_ground
    )
