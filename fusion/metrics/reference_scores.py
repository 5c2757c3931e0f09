"""Scores of tracks against an independent reference, in the manner of the airport
surveillance standards (EUROCAE ED-116 for SMR, ED-117 for MLAT) and the EUROCONTROL
surveillance performance specification (ESASSP, EUROCONTROL-SPEC-0147).

Arrays in (:class:`~.reference_association.TrackUpdates`,
:class:`~.reference_association.ReferenceSamples`), numbers out
(:class:`ReferenceScores`). Updates are associated to reference aircraft by the rule of
:mod:`.reference_association`; each measure is given for the surface, the airborne
phase and both (the phase is the reference's: its ground bit at the time).

* **Probability of update** (PoU). Each aircraft's presence segments (reference samples
  of one phase without a gap above ``max_reference_gap_s``) of duration D are cut into
  ⌊D / T⌋ consecutive windows of T = ``surface_window_s`` (1 s) or
  ``airborne_window_s`` (5 s) from the segment's start; a window is *updated* when at
  least one credited update of that aircraft, by any track, falls in it.
  PoU = updated windows / windows. (ED-116/ED-117 count expected and received reports
  per reference period this way, as ASTMOPS does; COMPASS's "Detection" requirement
  counts missed update intervals against expected ones.)
* **Horizontal position error** at the credited updates, the track's own times, the
  reference interpolated linearly (COMPASS "Position Distance RMS"): RMS, 95th
  percentile of |e|, the mean error (bias) east/north, and along/cross-track means for
  reference speeds ≥ ``min_offset_speed``. The reference's own error adds to it: with
  independent errors, E|e|² = E|track error|² + 2 σ_ref² (σ per axis), so the figure
  without the reference's share is √(RMS² − 2 mean σ_ref²) and that share is
  2 mean σ_ref² / RMS² (σ_ref from the reports' quality indicators; ADS-B NUCp/NACp give
  a 95 % bound, so this share is an upper bound). A time offset between the system
  and the reference shows as an along-track error: τ = (e · v) / |v|² per update
  (v the reference velocity), its median is the *lead* of the tracks over the
  reference (:func:`along_track_lead`).
* **Continuity.** Per aircraft, the *holder* of a window is, among the tracks credited
  in it, the one first credited to that aircraft (earliest). Track ids per aircraft:
  distinct tracks credited to it (over its credited updates of the phase); id changes:
  windows whose holder differs from the holder of the aircraft's previous window with
  one; the share of aircraft held by one id.
* **Duplicates** (multiple tracks): windows in which two or more tracks are credited to
  the same aircraft; a track is a duplicate track when it is credited but not the holder
  in at least ``min_duplicate_windows`` windows.
* **False tracks.** Along each track, a *stretch* is a run of consecutive updates not
  assigned to any aircraft, lasting from its first to its last update. A track is false
  when a stretch lasts more than ``false_track_s`` (30 s) while at least half of its
  updates are within ``near_reference_m`` of an aircraft the reference places at that
  time — the reference sees that area and its aircraft, and the track is not theirs
  (a ghost, a split or a drifting track). A stretch that long mostly away from every
  reported aircraft makes an **outside-reference** track instead: a target the
  reference never reports (a vehicle seen by the SMR only, an aircraft without ADS-B),
  or a false track where the reference has no aircraft — the reference cannot tell
  these apart, so they are counted separately, not as false. A track's phase is that
  of its own updates' ground flags when it has them, else of the nearest reference
  aircraft. Shorter misplacements are counted as *unassociated updates near the
  reference*: updates assigned to no aircraft while within ``near_reference_m`` of one
  (e.g. a track confirmed with a wrong velocity drifting off its aircraft).
* **Passing tracks** (``min_track_share`` > 0, off by default): a track assigned to an
  aircraft for less than that share of its updates is the track of an object the
  reference does not have (a vehicle parked beside a taxiway, seen by the SMR for the
  whole recording) whose few assignments are aircraft passing within the gate (50 m on
  the surface, 300 m airborne); none of its updates is credited, so it counts as an
  unassociated track (outside the reference, or false) rather than as one more track id
  and a few large errors of each aircraft that passed it.
* **What the inputs allow, and the assessed area** (:mod:`.reference_coverage`): with
  the tracker's input plots given, each phase also counts the windows the input reported
  (input-bound PoU) and the PoU over those windows; with an assessed area (polygons, a
  minimum surface speed), the windows, PoU and position error inside it — beside the
  unrestricted figures, never instead.
* **Correct identification** (ED-117 probability of correct identification; COMPASS
  "Identification Correct"): among credited updates that show a Mode-S address, the
  share equal to the reference aircraft's; the same for the callsign and the Mode-3/A
  code where the reference reports them (its last report at or before the update).

Times ns (int64); positions m in one east/north plane; durations s.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from pydantic import BaseModel, Field

from .reference_association import (
    Association,
    ReferenceIndex,
    ReferenceSamples,
    TrackUpdates,
    associate,
)
from .reference_coverage import (
    InputPlots,
    ScoreArea,
    assessed_updates,
    assessed_windows,
    input_windows,
)

PHASES = ("surface", "airborne", "all")


class ReferenceScoreConfig(BaseModel):
    """Parameters of :func:`score_against_reference` (module docstring)."""

    surface_window_s: float = Field(1.0, gt=0, description="Update window on the surface, s")
    airborne_window_s: float = Field(5.0, gt=0, description="Update window airborne, s")
    gate_surface_m: float = Field(50.0, gt=0, description="Association gate on the surface, m")
    gate_airborne_m: float = Field(300.0, gt=0, description="Association gate airborne, m")
    majority_window_s: float = Field(
        10.0, gt=0, description="Window of the majority vote along a track, s"
    )
    max_reference_gap_s: float = Field(
        6.0, gt=0, description="Longest reference gap interpolated across, s"
    )
    min_reference_samples: int = Field(
        10, ge=2, description="Reference aircraft with fewer samples are left out"
    )
    false_track_s: float = Field(
        30.0, gt=0, description="Unassociated longer than this: a false (or outside) track, s"
    )
    near_reference_m: float = Field(
        200.0, gt=0, description="A track this close to a reference aircraft is in its view, m"
    )
    min_duplicate_windows: int = Field(
        2, ge=1, description="Windows as a second track before a track is a duplicate"
    )
    min_offset_speed: float = Field(
        30.0, ge=0, description="Reference speed from which along-track errors give τ, m/s"
    )
    max_range_m: float | None = Field(
        None, gt=0, description="Score only within this distance of the plane's origin, m"
    )
    min_surface_speed: float = Field(
        0.0,
        ge=0,
        description="Assessed area: surface windows and updates where the reference moves "
        "slower than this are outside it (a parked aircraft is not on the manoeuvring area), "
        "m/s; 0: any speed",
    )
    speed_span_s: float = Field(
        10.0, gt=0, description="Span of the reference's speed for --min-surface-speed, s"
    )
    min_track_share: float = Field(
        0.0,
        ge=0,
        lt=1,
        description="Credit no aircraft with a track whose updates are assigned to an aircraft "
        "less than this share of the time (an object the reference does not have, passing "
        "by its aircraft); 0: every track",
    )


@dataclass(frozen=True)
class PositionScores:
    """Horizontal position error of credited updates (m; NaN when there are none)."""

    samples: int
    rms_m: float
    p95_m: float
    mean_east_m: float
    mean_north_m: float
    beyond_gate: int
    along_track_mean_m: float
    cross_track_mean_m: float
    lead_s: float
    lead_samples: int
    reference_sigma_m: float
    reference_share: float
    rms_without_reference_m: float


@dataclass(frozen=True)
class IdentityScore:
    """Credited updates showing the attribute (``checked``) and equal to the reference's."""

    checked: int
    correct: int

    @property
    def share(self) -> float:
        return self.correct / self.checked if self.checked else float("nan")


@dataclass(frozen=True)
class WindowCounts:
    """Update windows of one phase (:mod:`.reference_coverage`): ``windows``, those
    ``updated`` by a credited track; with the tracker's input given (else None), those
    reported by the input (``input``), reported and updated (``input_updated``), updated
    but not reported (``updated_without_input``)."""

    windows: int
    updated: int
    input: int | None = None
    input_updated: int | None = None
    updated_without_input: int | None = None

    @property
    def probability_of_update(self) -> float:
        return self.updated / self.windows if self.windows else float("nan")

    @property
    def input_bound(self) -> float | None:
        """Input-bound PoU: windows reported by the input / windows."""
        if self.input is None:
            return None
        return self.input / self.windows if self.windows else float("nan")

    @property
    def where_input(self) -> float | None:
        """PoU where the input reported: reported and updated / reported."""
        if self.input is None:
            return None
        return self.input_updated / self.input if self.input else float("nan")


@dataclass(frozen=True)
class AreaScores:
    """A phase restricted to the assessed area (:mod:`.reference_coverage`): its windows
    and the position error of its assessed credited updates."""

    aircraft: int
    counts: WindowCounts
    position: PositionScores


@dataclass(frozen=True)
class PhaseScores:
    """All measures of one phase (``surface``, ``airborne`` or ``all``); ``coverage``:
    the windows with the input's (:class:`WindowCounts`), ``area``: the same phase in the
    assessed area (None without one)."""

    aircraft: int
    windows: int
    windows_updated: int
    position: PositionScores
    aircraft_tracked: int
    track_ids_per_aircraft: float
    aircraft_on_one_id: float
    id_changes: int
    duplicate_windows: int
    duplicate_tracks: int
    false_tracks: int
    false_track_ids: tuple[int, ...]
    longest_false_s: float
    outside_reference_tracks: int
    unassociated_near: int
    mode_s: IdentityScore
    callsign: IdentityScore
    mode_3a: IdentityScore
    coverage: WindowCounts | None = None
    area: AreaScores | None = None

    @property
    def probability_of_update(self) -> float:
        return self.windows_updated / self.windows if self.windows else float("nan")

    @property
    def id_changes_per_aircraft(self) -> float:
        return self.id_changes / self.aircraft_tracked if self.aircraft_tracked else float("nan")

    @property
    def duplicate_window_share(self) -> float:
        return self.duplicate_windows / self.windows_updated if self.windows_updated else 0.0


@dataclass(frozen=True)
class AircraftScores:
    """Per reference aircraft (arrays over ``key``): update windows and updated windows
    on the surface and airborne, distinct tracks credited, id changes, position RMS (m,
    NaN without credited updates); with the input given, its windows reported by the
    input and those also updated, per phase (else None)."""

    key: np.ndarray
    windows_surface: np.ndarray
    updated_surface: np.ndarray
    windows_airborne: np.ndarray
    updated_airborne: np.ndarray
    tracks: np.ndarray
    id_changes: np.ndarray
    rms_m: np.ndarray
    input_surface: np.ndarray | None = None
    input_updated_surface: np.ndarray | None = None
    input_airborne: np.ndarray | None = None
    input_updated_airborne: np.ndarray | None = None


@dataclass(frozen=True)
class ReferenceScores:
    """:func:`score_against_reference`'s result: the three phases, the reference aircraft
    (``aircraft_keys``, and those left out for too few samples), the track updates scored
    and credited, the association itself and the time offset the reference was given."""

    surface: PhaseScores
    airborne: PhaseScores
    all: PhaseScores
    aircraft_keys: tuple[int, ...]
    dropped_aircraft: int
    updates: int
    credited: int
    tracks: int
    duration_s: float
    time_offset_s: float
    association: Association
    per_aircraft: AircraftScores


@dataclass(frozen=True)
class Windows:
    """The update windows of all aircraft (one row per window, aircraft by aircraft in
    time order: ``start`` s after the epoch, ``width`` s) and the (window, track) pairs of
    second tracks in them."""

    aircraft: np.ndarray
    start: np.ndarray
    width: np.ndarray
    ground: np.ndarray
    updated: np.ndarray
    n_tracks: np.ndarray
    change: np.ndarray
    extra_track: np.ndarray
    extra_ground: np.ndarray


def along_track_lead(err_x, err_y, vx, vy, min_speed: float) -> np.ndarray:
    """τ = (e · v) / |v|² (s) of each error ``e`` with reference velocity ``v`` faster than
    ``min_speed`` (m/s): how far ahead along the track the estimate is, in time; τ > 0:
    the track is where the reference will be τ later."""
    ex, ey, vx, vy = (np.asarray(a, float) for a in (err_x, err_y, vx, vy))
    v2 = vx * vx + vy * vy
    ok = np.isfinite(v2) & (v2 >= max(min_speed, 1e-9) ** 2) & np.isfinite(ex)
    return (ex[ok] * vx[ok] + ey[ok] * vy[ok]) / v2[ok]


def position_scores(assoc: Association, mask: np.ndarray, cfg: ReferenceScoreConfig):
    """:class:`PositionScores` of the credited updates in ``mask``."""
    m = mask & assoc.credited
    ex, ey = assoc.err_x[m], assoc.err_y[m]
    d = np.hypot(ex, ey)
    n = len(d)
    nan = float("nan")
    gate = np.where(assoc.ground[m], cfg.gate_surface_m, cfg.gate_airborne_m)
    vx, vy = assoc.vx[m], assoc.vy[m]
    v = np.hypot(vx, vy)
    moving = np.isfinite(v) & (v >= max(cfg.min_offset_speed, 1e-9))
    along = (ex[moving] * vx[moving] + ey[moving] * vy[moving]) / v[moving]
    cross = (ex[moving] * vy[moving] - ey[moving] * vx[moving]) / v[moving]
    lead = along_track_lead(ex, ey, vx, vy, cfg.min_offset_speed)
    sig = assoc.sigma[m]
    sig = sig[np.isfinite(sig)]
    rms = float(np.sqrt(np.mean(d * d))) if n else nan
    ref_var = float(np.mean(sig * sig)) if len(sig) else nan
    return PositionScores(
        samples=n,
        rms_m=rms,
        p95_m=float(np.percentile(d, 95)) if n else nan,
        mean_east_m=float(ex.mean()) if n else nan,
        mean_north_m=float(ey.mean()) if n else nan,
        beyond_gate=int((d > gate).sum()),
        along_track_mean_m=float(along.mean()) if len(along) else nan,
        cross_track_mean_m=float(cross.mean()) if len(cross) else nan,
        lead_s=float(np.median(lead)) if len(lead) else nan,
        lead_samples=len(lead),
        reference_sigma_m=float(np.sqrt(ref_var)) if len(sig) else nan,
        reference_share=min(1.0, 2 * ref_var / rms**2) if len(sig) and rms > 0 else nan,
        rms_without_reference_m=float(np.sqrt(max(rms**2 - 2 * ref_var, 0.0)))
        if len(sig) and n
        else nan,
    )


def _aircraft_windows(a, ref: ReferenceIndex, t, track, cfg) -> tuple[np.ndarray, ...] | None:
    """Windows of aircraft ``a``: (ground, updated, n_tracks, holder, extra tracks, extra
    window rows, start, width), from the credited update times ``t`` (s) and tracks ``track``."""
    seg = ref.segments[a]
    width = np.where(seg[:, 2] == 1, cfg.surface_window_s, cfg.airborne_window_s)
    n_win = np.floor((seg[:, 1] - seg[:, 0]) / width + 1e-9).astype(np.int64)
    total = int(n_win.sum())
    if total == 0:
        return None
    sid = np.repeat(np.arange(len(seg)), n_win)
    k = np.arange(total) - np.repeat(np.cumsum(n_win) - n_win, n_win)
    w0 = seg[sid, 0] + k * width[sid]
    w1 = w0 + width[sid]
    ground = seg[sid, 2] == 1
    j = np.searchsorted(w0, t, side="right") - 1
    inside = (j >= 0) & (t < w1[np.clip(j, 0, None)])
    j, trk = j[inside], track[inside]
    # holder order: the track first credited to this aircraft first
    by_t = np.argsort(t, kind="stable")
    names, first = np.unique(track[by_t], return_index=True)
    rank_of = np.argsort(np.argsort(t[by_t][first], kind="stable"), kind="stable")
    rank = rank_of[np.searchsorted(names, trk)]
    pairs = np.unique(np.column_stack([j, rank]), axis=0) if len(j) else np.zeros((0, 2), int)
    head = np.r_[True, pairs[1:, 0] != pairs[:-1, 0]] if len(pairs) else np.zeros(0, bool)
    updated = np.zeros(total, bool)
    updated[pairs[head, 0]] = True
    n_tracks = np.bincount(pairs[:, 0], minlength=total)
    holder = np.full(total, -1, np.int64)
    holder[pairs[head, 0]] = names[np.argsort(rank_of)][pairs[head, 1]]
    extra = pairs[~head]
    extra_track = names[np.argsort(rank_of)][extra[:, 1]] if len(extra) else np.zeros(0, int)
    return ground, updated, n_tracks, holder, extra_track, extra[:, 0], w0, width[sid]


def reference_windows(
    updates: TrackUpdates, assoc: Association, ref: ReferenceIndex, epoch_ns: int, cfg
) -> Windows:
    """The windows of every reference aircraft (module docstring: PoU, continuity,
    duplicates)."""
    t = (updates.time_ns - epoch_ns) * 1e-9
    cred = np.flatnonzero(assoc.credited)
    by_aircraft = cred[np.argsort(assoc.assigned[cred], kind="stable")]
    owner = assoc.assigned[by_aircraft]
    cols: list[list[np.ndarray]] = [[] for _ in range(9)]
    for a in range(len(ref)):
        lo, hi = np.searchsorted(owner, a, "left"), np.searchsorted(owner, a, "right")
        idx = by_aircraft[lo:hi]
        got = _aircraft_windows(a, ref, t[idx], updates.track_id[idx], cfg)
        if got is None:
            continue
        ground, updated, n_tracks, holder, extra_track, extra_row, w0, width = got
        seq = holder[holder >= 0]
        change = np.zeros(len(holder), bool)
        change[np.flatnonzero(holder >= 0)[1:]] = seq[1:] != seq[:-1]
        for c, v in zip(cols, (np.full(len(holder), a), w0, width, ground, updated, n_tracks,
                               change, extra_track, ground[extra_row])):  # fmt: skip
            c.append(v)
    dtypes = (np.int64, float, float, bool, bool, np.int64, bool, np.int64, bool)
    return Windows(*(np.concatenate(c) if c else np.zeros(0, d) for c, d in zip(cols, dtypes)))


@dataclass(frozen=True)
class Stretches:
    """Unassociated stretches longer than ``false_track_s``: ``track``, ``duration_s``,
    ``false`` (mostly near reported aircraft) and ``ground`` (1, 0, −1 unknown)."""

    track: np.ndarray
    duration_s: np.ndarray
    false: np.ndarray
    ground: np.ndarray


def unassociated_stretches(updates: TrackUpdates, assoc: Association, cfg) -> Stretches:
    """The stretches of the false-track rule (module docstring)."""
    order = np.lexsort((updates.time_ns, updates.track_id))
    trk = updates.track_id[order]
    t = updates.time_ns[order] * 1e-9
    un = assoc.assigned[order] < 0
    head = np.ones(min(len(trk), 1), bool)
    start = np.flatnonzero(np.r_[head, (trk[1:] != trk[:-1]) | (un[1:] != un[:-1])])
    stop = np.r_[start[1:], len(trk)]
    keep = un[start]
    start, stop = start[keep], stop[keep]
    dur = t[stop - 1] - t[start]
    long = dur > cfg.false_track_s
    start, stop, dur = start[long], stop[long], dur[long]
    near = (assoc.nearest_m[order] <= cfg.near_reference_m).astype(float)
    own = updates.ground[order].astype(float)
    ref_g = assoc.nearest_ground[order].astype(float)
    ground = np.full(len(start), -1, np.int8)
    false = np.zeros(len(start), bool)
    for i, (lo, hi) in enumerate(zip(start, stop)):
        false[i] = near[lo:hi].mean() >= 0.5
        for flags in (own[lo:hi], ref_g[lo:hi]):
            known = flags[flags >= 0]
            if len(known):
                ground[i] = int(known.mean() >= 0.5)
                break
    return Stretches(trk[start], dur, false, ground)


def aircraft_scores(ref: ReferenceIndex, win: Windows, assoc: Association, track_id, hit=None):
    """:class:`AircraftScores` from the windows and the credited updates (``hit``: the
    windows reported by the input, or None)."""
    n = len(ref)

    def count(mask):
        return np.bincount(win.aircraft[mask], minlength=n)

    cred = np.flatnonzero(assoc.credited)
    a = assoc.assigned[cred]
    pairs = np.unique(np.column_stack([a, track_id[cred]]), axis=0)
    sq = np.bincount(a, weights=assoc.err_x[cred] ** 2 + assoc.err_y[cred] ** 2, minlength=n)
    k = np.bincount(a, minlength=n)
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(sq / k)
    return AircraftScores(
        key=ref.keys.copy(),
        windows_surface=count(win.ground), updated_surface=count(win.ground & win.updated),
        windows_airborne=count(~win.ground), updated_airborne=count(~win.ground & win.updated),
        tracks=np.bincount(pairs[:, 0], minlength=n) if len(pairs) else np.zeros(n, np.int64),
        id_changes=count(win.change), rms_m=rms,
        **({} if hit is None else {
            "input_surface": count(win.ground & hit),
            "input_updated_surface": count(win.ground & hit & win.updated),
            "input_airborne": count(~win.ground & hit),
            "input_updated_airborne": count(~win.ground & hit & win.updated),
        }),
    )  # fmt: skip


def _identity(updates, assoc, ref: ReferenceIndex, m: np.ndarray) -> tuple[IdentityScore, ...]:
    """Mode-S, callsign and Mode-3/A checks of the credited updates in ``m``."""
    idx = np.flatnonzero(m & assoc.credited)
    a = assoc.assigned[idx]
    ms = updates.mode_s[idx]
    out = [IdentityScore(int((ms >= 0).sum()), int((ms == ref.keys[a]).sum()))]
    t = (updates.time_ns[idx] - ref.epoch_ns) * 1e-9
    for name, unknown in (("callsign", None), ("mode_3a", -1)):
        mine = getattr(updates, name)[idx]
        theirs = np.empty(len(idx), dtype=mine.dtype)
        for k in np.unique(a).tolist():
            sel = a == k
            theirs[sel] = ref.identity_at(k, t[sel], name)
        if name == "callsign":
            mine = np.array([None if v is None else str(v).strip() for v in mine], object)
            theirs = np.array([None if v is None else str(v).strip() for v in theirs], object)
            both = np.array([u is not None and v is not None for u, v in zip(mine, theirs)],
                            bool)  # fmt: skip
        else:
            both = (mine != unknown) & (theirs != unknown)
        out.append(IdentityScore(int(both.sum()), int((both & (mine == theirs)).sum())))
    return tuple(out)


def _continuity(updates, assoc, m) -> tuple[int, float, float]:
    """(aircraft tracked, track ids per aircraft, share on one id) over credited ``m``."""
    idx = np.flatnonzero(m & assoc.credited)
    if not len(idx):
        return 0, float("nan"), float("nan")
    pairs = np.unique(np.column_stack([assoc.assigned[idx], updates.track_id[idx]]), axis=0)
    _, ids = np.unique(pairs[:, 0], return_counts=True)
    return len(ids), float(ids.mean()), float((ids == 1).mean())


def window_counts(win: Windows, wm: np.ndarray, hit: np.ndarray | None) -> WindowCounts:
    """:class:`WindowCounts` of the windows ``wm``; ``hit``: reported by the input."""
    updated = int((wm & win.updated).sum())
    if hit is None:
        return WindowCounts(int(wm.sum()), updated)
    return WindowCounts(
        int(wm.sum()), updated, int((wm & hit).sum()), int((wm & hit & win.updated).sum()),
        int((wm & ~hit & win.updated).sum()),
    )  # fmt: skip


@dataclass(frozen=True)
class WindowFlags:
    """Per window: reported by the input (``hit``, None without input), in the assessed
    area (``assessed``, None without one); per update: credited and assessed
    (``assessed_updates``)."""

    hit: np.ndarray | None = None
    assessed: np.ndarray | None = None
    assessed_updates: np.ndarray | None = None


def _area(assoc, win: Windows, wm, m, flags: WindowFlags, cfg) -> AreaScores | None:
    """The phase (windows ``wm``, updates ``m``) in the assessed area, or None."""
    if flags.assessed is None:
        return None
    wa = wm & flags.assessed
    return AreaScores(
        aircraft=len(np.unique(win.aircraft[wa])),
        counts=window_counts(win, wa, flags.hit),
        position=position_scores(assoc, m & flags.assessed_updates, cfg),
    )


def _phase(updates, assoc, ref, win: Windows, st: Stretches, which: str, cfg,
           flags: WindowFlags | None = None) -> PhaseScores:  # fmt: skip
    """The measures of one phase from the per-update, per-window and stretch arrays."""
    flags = flags or WindowFlags()
    sel = {"surface": (1,), "airborne": (0,), "all": (0, 1, -1)}[which]
    m = np.isin(assoc.ground.astype(np.int8), sel)
    wm = np.isin(win.ground.astype(np.int8), sel)
    tracked, ids, one = _continuity(updates, assoc, m)
    extra = win.extra_track[np.isin(win.extra_ground.astype(np.int8), sel)]
    _, counts = np.unique(extra, return_counts=True)
    sm = np.isin(st.ground, sel)
    false_ids = np.unique(st.track[sm & st.false])
    outside = np.setdiff1d(np.unique(st.track[sm & ~st.false]), false_ids)
    ms, cs, m3 = _identity(updates, assoc, ref, m)
    near = (assoc.assigned < 0) & (assoc.nearest_m <= cfg.near_reference_m)
    near &= np.isin(assoc.nearest_ground, sel)
    return PhaseScores(
        aircraft=len(np.unique(win.aircraft[wm])),
        windows=int(wm.sum()),
        windows_updated=int((wm & win.updated).sum()),
        position=position_scores(assoc, m, cfg),
        aircraft_tracked=tracked,
        track_ids_per_aircraft=ids,
        aircraft_on_one_id=one,
        id_changes=int((wm & win.change).sum()),
        duplicate_windows=int((wm & (win.n_tracks >= 2)).sum()),
        duplicate_tracks=int((counts >= cfg.min_duplicate_windows).sum()),
        false_tracks=len(false_ids),
        false_track_ids=tuple(int(i) for i in false_ids),
        longest_false_s=float(st.duration_s[sm & st.false].max()) if (sm & st.false).any() else 0.0,
        outside_reference_tracks=len(outside),
        unassociated_near=int(near.sum()),
        mode_s=ms,
        callsign=cs,
        mode_3a=m3,
        coverage=window_counts(win, wm, flags.hit),
        area=_area(assoc, win, wm, m, flags, cfg),
    )


def window_flags(updates, assoc, ref, win: Windows, epoch: int, cfg, plots, area) -> WindowFlags:
    """The input's windows (with ``plots``) and the assessed area's (when it restricts)."""
    hit = None
    if plots is not None:
        hit = input_windows(plots, ref, win.aircraft, win.start, win.width, epoch, cfg)
    if not area.restricts:
        return WindowFlags(hit)
    t = (updates.time_ns - epoch) * 1e-9
    return WindowFlags(
        hit,
        assessed_windows(area, ref, win.aircraft, win.start, win.width),
        assessed_updates(area, ref, assoc, t),
    )


def without_passing_tracks(track_id: np.ndarray, assoc: Association, share: float) -> Association:
    """``assoc`` with no update credited of the tracks assigned to an aircraft for less
    than ``share`` of their updates (module docstring, passing tracks)."""
    ids, inv = np.unique(track_id, return_inverse=True)
    assigned = np.bincount(inv, assoc.assigned >= 0, minlength=len(ids))
    drop = (assigned / np.bincount(inv, minlength=len(ids)))[inv] < share
    if not drop.any():
        return assoc
    nan = np.where(drop, np.nan, 1.0)
    return replace(
        assoc, assigned=np.where(drop, -1, assoc.assigned), credited=assoc.credited & ~drop,
        err_x=assoc.err_x * nan, err_y=assoc.err_y * nan,
    )  # fmt: skip


def score_against_reference(
    updates: TrackUpdates,
    reference: ReferenceSamples,
    config: ReferenceScoreConfig | None = None,
    *,
    time_offset_s: float = 0.0,
    plots: InputPlots | None = None,
    area_polygons: Sequence[np.ndarray] = (),
) -> ReferenceScores:
    """Score the track ``updates`` against ``reference`` (module docstring), the
    reference's time stamps moved by ``time_offset_s`` seconds first; ``plots``: the
    tracker's input, for the input bound, ``area_polygons`` ((k, 2) m in the plane) and
    ``config.min_surface_speed``: the assessed area (:mod:`.reference_coverage`)."""
    cfg = config or ReferenceScoreConfig()
    if time_offset_s:
        reference = reference.shifted(time_offset_s)
    if cfg.max_range_m is not None:
        updates = updates.take(np.hypot(updates.x, updates.y) <= cfg.max_range_m)
        reference = reference.take(np.hypot(reference.x, reference.y) <= cfg.max_range_m)
        if plots is not None:
            plots = plots.take(np.hypot(plots.x, plots.y) <= cfg.max_range_m)
    times = [a.min() for a in (updates.time_ns, reference.time_ns) if len(a)]
    epoch = int(min(times)) if times else 0
    ref = ReferenceIndex.build(reference, epoch, cfg.max_reference_gap_s, cfg.min_reference_samples)
    assoc = associate(
        updates, ref, epoch, gate_surface_m=cfg.gate_surface_m,
        gate_airborne_m=cfg.gate_airborne_m, majority_window_s=cfg.majority_window_s,
    )  # fmt: skip
    if cfg.min_track_share > 0:
        assoc = without_passing_tracks(updates.track_id, assoc, cfg.min_track_share)
    win = reference_windows(updates, assoc, ref, epoch, cfg)
    st = unassociated_stretches(updates, assoc, cfg)
    area = ScoreArea(tuple(area_polygons), cfg.min_surface_speed, cfg.speed_span_s)
    flags = window_flags(updates, assoc, ref, win, epoch, cfg, plots, area)
    phases = {p: _phase(updates, assoc, ref, win, st, p, cfg, flags) for p in PHASES}
    t = updates.time_ns
    return ReferenceScores(
        **phases,
        aircraft_keys=tuple(int(k) for k in ref.keys),
        dropped_aircraft=ref.dropped_aircraft,
        updates=len(updates),
        credited=int(assoc.credited.sum()),
        tracks=len(np.unique(updates.track_id)),
        duration_s=float((t.max() - t.min()) * 1e-9) if len(t) else 0.0,
        time_offset_s=float(time_offset_s),
        association=assoc,
        per_aircraft=aircraft_scores(ref, win, assoc, updates.track_id, flags.hit),
    )
