"""What the inputs allow, and the assessed area, for the reference scores of
:mod:`.reference_scores`.

**Input bound.** A tracker cannot update a track in a window where no sensor reported
the aircraft. A window of aircraft *a* (the update windows of :mod:`.reference_scores`:
T = 1 s on the surface, 5 s airborne) is *reported by the input* when a plot the tracker
was given

* lies within the scorer's association gate (``gate_surface_m`` / ``gate_airborne_m``,
  the same as for track updates) of *a*'s reference position interpolated at the plot's
  own time, and *a* is the nearest such aircraft (step 1 of the association rule of
  :mod:`.reference_association`); a plot that shows a Mode-S address (MLAT, ADS-B) is
  labelled only to the aircraft of that address — identity tells aircraft apart here, in
  the scoring, and never drives the association of tracks;
* falls in the window by the time the tracker had it (``window_time_ns``: the time of
  the batch it came in, which is the time stamp of the track update it can cause; its
  own time by default).

Per phase: *input-bound PoU* = windows reported by the input / windows, and the *PoU
where the input reported* = windows reported and updated by a credited track / windows
reported. Windows updated although no plot of the aircraft was within the gate (a track
fed by a plot of a neighbour, or coasting into the gate) are counted apart.

**Assessed area.** EUROCAE ED-116 (SMR) and ED-117 (MLAT) state their requirements for
targets in the system's coverage volume — for a surface movement radar, the manoeuvring
area. A window is *assessed* when the reference position at the window's middle lies
inside one of the area's polygons (even-odd rule, :func:`~skyfuse.fusion.tracker
.coverage_polygon.inside`; all of the plane when none is given) and, on the surface, the
reference moves at least ``min_surface_speed``: |p(t + s/2) − p(t − s/2)| / s over
``speed_span_s`` = s (times clipped to the aircraft's reports; a span, not successive
reports, since a stationary aircraft's MLAT positions scatter by metres each second). A
credited update is assessed by the same test at its own time. Measures restricted to
assessed windows and updates are always reported beside the unrestricted ones.

Times ns (int64) in, s after the scorer's epoch inside; positions m, one plane.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skyfuse.fusion.tracker.coverage_polygon import inside

from .reference_association import (
    Association,
    ReferenceIndex,
    _column,
    _finite,
    _times,
    nearest_labels,
)

_PLOT_FIELDS = ("time_ns", "x", "y", "window_time_ns", "mode_s")


@dataclass(frozen=True)
class InputPlots:
    """The plots a tracker was given: ``time_ns`` (n,) int64 the plot's time, ``x``, ``y``
    (n,) m east/north in the scorer's plane; optional ``window_time_ns`` (n,) int64 the
    time the tracker had it (default ``time_ns``) and ``mode_s`` (n,) int64 (−1 unknown)."""

    time_ns: np.ndarray
    x: np.ndarray
    y: np.ndarray
    window_time_ns: np.ndarray | None = None
    mode_s: np.ndarray | None = None

    def __post_init__(self) -> None:
        t = _times("time_ns", self.time_ns)
        n = len(t)
        tw = t if self.window_time_ns is None else _times("window_time_ns", self.window_time_ns)
        if len(tw) != n:
            raise ValueError(f"window_time_ns: shape {tw.shape}: must be ({n},)")
        cols = {
            "time_ns": t,
            "x": _finite("x", self.x, n),
            "y": _finite("y", self.y, n),
            "window_time_ns": tw,
            "mode_s": _column("mode_s", self.mode_s, n, np.int64, -1),
        }
        for k, v in cols.items():
            object.__setattr__(self, k, v)

    def __len__(self) -> int:
        return len(self.time_ns)

    def take(self, rows) -> InputPlots:
        """The plots ``rows`` (indices or a boolean mask)."""
        return InputPlots(*(getattr(self, k)[rows] for k in _PLOT_FIELDS))

    @classmethod
    def concat(cls, parts: list[InputPlots]) -> InputPlots:
        if not parts:
            z = np.zeros(0, np.int64)
            return cls(z, np.zeros(0), np.zeros(0))
        return cls(*(np.concatenate([getattr(p, k) for p in parts]) for k in _PLOT_FIELDS))


def _aircraft_rows(win_aircraft: np.ndarray, a: int) -> slice:
    """The rows of aircraft ``a`` in the windows (grouped by aircraft, ascending)."""
    lo, hi = np.searchsorted(win_aircraft, [a, a + 1], "left")
    return slice(int(lo), int(hi))


def window_of(start: np.ndarray, width: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(n,) index of the window [start, start + width) holding each time ``t``, −1 none;
    ``start`` ascending, windows disjoint."""
    j = np.searchsorted(start, t, side="right") - 1
    ok = (j >= 0) & (t < start[np.clip(j, 0, None)] + width[np.clip(j, 0, None)])
    return np.where(ok, j, -1)


def plot_labels(plots: InputPlots, ref: ReferenceIndex, epoch_ns: int, cfg) -> np.ndarray:
    """(n,) the aircraft (index into ``ref.keys``, −1 none) each plot reports (module
    docstring)."""
    t = (plots.time_ns - epoch_ns) * 1e-9
    label, *_ = nearest_labels(
        t, plots.x, plots.y, ref, cfg.gate_surface_m, cfg.gate_airborne_m, known_key=plots.mode_s
    )
    return label


def input_windows(
    plots: InputPlots, ref: ReferenceIndex, win_aircraft, win_start, win_width, epoch_ns, cfg
) -> np.ndarray:
    """(w,) bool: the window (rows of ``win_*``, grouped by aircraft) is reported by the
    input (module docstring)."""
    hit = np.zeros(len(win_aircraft), bool)
    if not len(plots) or not len(win_aircraft):
        return hit
    label = plot_labels(plots, ref, epoch_ns, cfg)
    tw = (plots.window_time_ns - epoch_ns) * 1e-9
    for a in np.unique(label[label >= 0]).tolist():
        rows = _aircraft_rows(win_aircraft, a)
        j = window_of(win_start[rows], win_width[rows], tw[label == a])
        hit[rows.start + j[j >= 0]] = True
    return hit


@dataclass(frozen=True)
class ScoreArea:
    """The assessed area (module docstring): ``polygons`` (k, 2) vertex arrays in the
    scorer's plane, m (none: everywhere), ``min_surface_speed`` m/s (0: any speed),
    ``speed_span_s`` s."""

    polygons: tuple[np.ndarray, ...] = ()
    min_surface_speed: float = 0.0
    speed_span_s: float = 10.0

    def __post_init__(self) -> None:
        polys = tuple(np.asarray(p, np.float64) for p in self.polygons)
        for i, p in enumerate(polys):
            if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3 or not np.isfinite(p).all():
                raise ValueError(f"polygon {i}: shape {p.shape}: must be (k >= 3, 2), finite")
        object.__setattr__(self, "polygons", polys)
        if not (self.min_surface_speed >= 0 and self.speed_span_s > 0):
            raise ValueError(
                f"min_surface_speed {self.min_surface_speed}, speed_span_s "
                f"{self.speed_span_s}: must be >= 0 and > 0"
            )

    @property
    def restricts(self) -> bool:
        return bool(self.polygons) or self.min_surface_speed > 0

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """(n,) bool: inside any polygon (everywhere without polygons)."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        if not self.polygons:
            return np.ones(x.shape, bool)
        p = np.column_stack([x, y])
        out = np.zeros(len(p), bool)
        for poly in self.polygons:  # only the points in a polygon's bounding box are tested
            lo, hi = poly.min(axis=0), poly.max(axis=0)
            box = np.flatnonzero(((p >= lo) & (p <= hi)).all(axis=1) & ~out)
            out[box[inside(p[box], poly)]] = True
        return out


def reference_speed(ref: ReferenceIndex, a: int, t: np.ndarray, span_s: float) -> np.ndarray:
    """(n,) aircraft ``a``'s speed at times ``t``, m/s: displacement over ``span_s``
    centred on t, the ends clipped to its first and last report (0 where they meet)."""
    t0, t1 = ref.span(a)
    lo = np.clip(t - 0.5 * span_s, t0, t1)
    hi = np.clip(t + 0.5 * span_s, t0, t1)
    p, q = ref.at(a, lo), ref.at(a, hi)
    dt = hi - lo
    with np.errstate(invalid="ignore", divide="ignore"):
        v = np.hypot(q.x - p.x, q.y - p.y) / dt
    return np.where(dt > 0, v, 0.0)


def _assessed_at(area: ScoreArea, ref: ReferenceIndex, a: int, t: np.ndarray) -> np.ndarray:
    """(n,) bool: aircraft ``a`` at times ``t`` is in the assessed area."""
    p = ref.at(a, t)
    ok = area.contains(p.x, p.y)
    if area.min_surface_speed > 0:
        slow = reference_speed(ref, a, t, area.speed_span_s) < area.min_surface_speed
        ok &= ~(p.ground & slow)
    return ok


def assessed_windows(area: ScoreArea, ref: ReferenceIndex, win_aircraft, win_start, win_width):
    """(w,) bool: the window's middle is in the assessed area (module docstring)."""
    out = np.ones(len(win_aircraft), bool)
    if not area.restricts:
        return out
    for a in np.unique(win_aircraft).tolist():
        rows = _aircraft_rows(win_aircraft, a)
        out[rows] = _assessed_at(area, ref, a, win_start[rows] + 0.5 * win_width[rows])
    return out


def assessed_updates(area: ScoreArea, ref: ReferenceIndex, assoc: Association, t: np.ndarray):
    """(n,) bool: the update is credited and its aircraft, at the update's time ``t`` (s
    after the epoch), is in the assessed area."""
    out = assoc.credited.copy()
    if not area.restricts:
        return out
    for a in np.unique(assoc.assigned[assoc.credited]).tolist():
        idx = np.flatnonzero(assoc.credited & (assoc.assigned == a))
        out[idx] = _assessed_at(area, ref, a, t[idx])
    return out
