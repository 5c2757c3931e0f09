"""CAT010 / CAT020 / CAT021 target reports → :class:`schemas.PlotBatch` batches of their
sensors: multilateration, surface movement radar (SMR) and ADS-B become sensors like a
radar, each with its own id, site and batches.

**Which sensor.** A report's sensor is its data source and its technology:

======================================  ==========  =====================================
reports                                 sensor      id
======================================  ==========  =====================================
CAT010 I020 TYP 0, 1, 5 (SSR, Mode S,   ``mlat``    ``"SAC-SIC"``
HF multilateration); CAT020
CAT010 TYP 3 (PSR: an SMR)              ``smr``     ``"SAC-SIC"``
CAT021; CAT010 TYP 2                    ``adsb``    ``"SAC-SIC-adsb"`` (a multilateration
                                                    system sends its own ADS-B under its
                                                    SAC/SIC: LEBL's SAC 0 / SIC 107)
======================================  ==========  =====================================

Other CAT010 types (magnetic loop, other) are counted (``report_type_not_tracked``) and
dropped, as are **field monitors** (I020 RAB = 1: the system's own fixed transponders,
``report_field_monitors``), simulated reports with ``skip_simulated`` and **track ends**
without a position (the SMR sends I161 + I170 TRE = 1 only: ``report_track_ends``).
Test targets (TST = 1) never reach here (:mod:`.surveillance` drops them).

**Batches.** A multilateration system or an SMR sends a *start of update cycle* message
(CAT010 type 2) every cycle (1 s at LEBL): a sensor's batch holds its reports between two
of them, in arrival order, and ends at the cycle message's time (widened to cover its
reports: SMR reports arrive in sweep order, some timed up to 0.2 s before the message
that precedes them); a cycle without reports is an empty batch (the sensor looked and saw
nothing). Without cycle messages (CAT020, CAT021, or after more than three cycles without
one: ``report_cycles_lost``) a batch is a fixed time window of ``window`` seconds
(boundaries at multiples of it, so a live feed and a file cut the same batches); a window
without reports gives no batch (no report at all: the feed is silent, which says nothing
about any target). A batch never holds two reports of one target (the sensor's track
number, else the address): a repeat closes the batch before it
(``report_batch_split``; ADS-B aircraft report about twice a second). Reports are sorted
by time inside a batch.

**Columns.** The plot geometry is the site's kind: ``cartesian`` from I042 (x east, y north
of the site, m), ``2d`` from I040 (ρ, θ: polar plots, placed at the site's height, the
airport surface: give an SMR's ``alt`` as the surface height), ``wgs84`` from I041 /
CAT021's position (default: the first report's, I042 first); a report without that
geometry is counted (``report_no_position_for_kind``). An SMR plot is the centroid of its
target's echo, while multilateration and ADS-B report the aircraft's antenna, anywhere
along its length L (I270: median 19 m, p90 46 m at LEBL): its σ per axis is
√(σ_c² + L²/12) (the variance of a point uniform along L), so that the plots of one
aircraft from the three sensors meet in one track's gate.

``altitude``: the geometric height when reported (CAT021
geometric height, CAT020 I110, CAT010 I091), else the flight level as a height (as for
CAT048); ``sigma``: multilateration I500 √((σx² + σy²)/2), ADS-B the σ of its NACp/NUCp
(:mod:`skyfuse.schemas.adsb_quality`) or ``adsb_sigma`` (an empirical σ for every ADS-B
report); an ADS-B report whose quality gives no σ (NUCp 0) is dropped (``adsb_no_accuracy``) unless
``adsb_sigma`` is set. ``v_east``/``v_north``: I202 (CAT010), VX/VY (CAT020), the ADS-B
velocity (σ from NUCr/NACv); ``flight_status`` 1 (on the ground) for the ground bit; the
identity (``mode_s``, ``mode_3a``, ``callsign``, ``flight_level``) for evaluation and
display, never to associate.

**Sites.** A sensor's site is its sites-file table (SAC/SIC; ``adsb = true`` for the ADS-B
id) with the fields the table does not give taken from :data:`SENSOR_DEFAULTS` of its kind
(working defaults; the table wins), the kind from the first report's geometry and the
cycle period measured from the cycle messages (median of the last 64). An ADS-B sensor
without a table is placed at the site of its SAC/SIC's other sensor, else at its first
report (its reports carry their own positions; the site only anchors the range ring). A
multilateration system or SMR without a table has no site (its positions are relative to
it): its batches are still emitted and the reader says which table is missing.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pydantic import ValidationError
from skyfuse.schemas import PlotBatch, RadarKind, RadarSite
from skyfuse.schemas.identity import CALLSIGN_RE, FLIGHT_LEVEL_MAX, FLIGHT_LEVEL_MIN

from . import cat010, cat020, cat021
from .sites import radar_id_for

MLAT, SMR, ADSB = "mlat", "smr", "adsb"
MLAT_TYPES = frozenset({0, 1, 5})
ADSB_TYPE, PSR_TYPE = 2, 3
FT = 0.3048
ALTITUDE_FL = (-30.0, 3000.0)
MAX_REPORTS_PER_BATCH = 5000
MAX_SENSORS = 256
CYCLES_LOST_AFTER = 3.0
"""A cycled sensor falls back to windows after this many cycle periods without a cycle
message."""

SENSOR_DEFAULTS: dict[str, dict] = {
    MLAT: {"detection": "reports", "report_timeout": 5.0, "p_detection": 0.9,
           "sigma_cartesian": 5.0, "sigma_growth": 2.5e-3, "max_range": 60_000.0},
    SMR: {"detection": "reports", "report_timeout": 10.0, "timing": "plots", "p_detection": 0.8,
          "sigma_cartesian": 12.0, "sigma_range": 7.5, "sigma_azimuth": 0.0015,
          "sigma_altitude": 5.0, "max_range": 8_000.0},
    ADSB: {"kind": "wgs84", "detection": "reports", "report_timeout": 10.0,
           "p_detection": 0.9, "sigma_cartesian": 38.0, "max_range": 250_000.0},
}  # fmt: skip
"""The site fields a sensor of each kind gets when its sites-file table does not give
them (a starting point: docs/concepts/sensors.md says how they were chosen). The SMR's
ceiling is its site height + :data:`SMR_CEILING_M`. The SMR sweeps, but its detection map
is not known (buildings and parked aircraft shadow stands, aircraft on approach are under
its ceiling but outside its beam): its silence is a miss only for a track it detected
within ``report_timeout`` (``detection = "reports"``), measured on LEBL 2016
(docs/real-data.md)."""
SMR_CEILING_M = 300.0


@dataclass
class _Sensor:
    """One report-based sensor's batching state (module docstring)."""

    radar_id: str
    sac: int
    sic: int
    kind: str
    first: object
    reports: list = field(default_factory=list)
    keys: set = field(default_factory=set)
    start: int | None = None
    window_end: int | None = None
    cycled: bool = False
    last_cycle: int | None = None
    periods: deque = field(default_factory=lambda: deque(maxlen=64))
    seq: int = 0
    plots: int = 0


def sensor_kind(report) -> str | None:
    """``mlat``, ``smr``, ``adsb`` or None (not tracked) of a target report."""
    if isinstance(report, cat021.Cat021Report):
        return ADSB
    if isinstance(report, cat020.Cat020Report):
        return MLAT
    typ = report.typ
    if typ in MLAT_TYPES:
        return MLAT
    return {PSR_TYPE: SMR, ADSB_TYPE: ADSB}.get(typ)


class ReportBatcher:
    """Reports in, sensor batches out (module docstring). ``sites``: radar id →
    RadarSite of the sites file; ``stats``/``note``: the reader's counters and message
    list; ``window``: the batch window of sensors without cycle messages, s."""

    def __init__(
        self,
        *,
        sites: dict[str, RadarSite] | None = None,
        stats: Counter | None = None,
        note: Callable[[str], None] = lambda text: None,
        window: float = 1.0,
        adsb_sigma: float | None = None,
        skip_simulated: bool = False,
    ) -> None:
        if not 0.05 <= window <= 60.0:
            raise ValueError(f"report window = {window} s: must be in [0.05, 60]")
        if adsb_sigma is not None and not 0.01 <= adsb_sigma <= 10_000.0:
            raise ValueError(f"adsb_sigma = {adsb_sigma} m: must be in [0.01, 10000]")
        self.input_sites = dict(sites or {})
        self.stats = stats if stats is not None else Counter()
        self.note = note
        self.window_ns = round(window * 1e9)
        self.adsb_sigma = adsb_sigma
        self.skip_simulated = skip_simulated
        self._sensors: dict[str, _Sensor] = {}
        self._cycle_marks: dict[str, int] = {}

    # ------------------------------------------------------------------ input
    def add(self, item) -> list[tuple[PlotBatch, list[int]]]:
        """One decoded report or status message; returns the batches it completed (with
        the report types of their plots)."""
        out: list[tuple[PlotBatch, list[int]]] = []
        if isinstance(item, cat010.Cat010Status):
            if item.message_type == cat010.START_OF_UPDATE_CYCLE and item.time_ns is not None:
                self._cycle(radar_id_for(item.sac, item.sic), item.time_ns, out)
            return out
        kind = sensor_kind(item)
        if not self._usable(item, kind):
            return out
        rid = radar_id_for(item.sac, item.sic, kind == ADSB)
        sensor = self._sensor(rid, kind, item)
        if sensor is not None:
            self._add_report(sensor, item, out)
        return out

    def flush(self) -> list[tuple[PlotBatch, list[int]]]:
        """Close every sensor's open batch (end of the input)."""
        out: list[tuple[PlotBatch, list[int]]] = []
        for s in self._sensors.values():
            if s.reports:
                self._emit(s, max(r.time_ns for r in s.reports), out)
        return out

    def _usable(self, r, kind: str | None) -> bool:
        """Whether a target report goes to a sensor; the others are counted."""
        if kind is None:
            self.stats["report_type_not_tracked"] += 1
        elif getattr(r, "rab", False):
            self.stats["report_field_monitors"] += 1
        elif self.skip_simulated and r.sim:
            self.stats["report_simulated_skipped"] += 1
        elif _position_free(r):
            self.stats["report_track_ends"] += 1
        elif r.time_ns is None:
            self.stats["report_no_time"] += 1
        else:
            return True
        return False

    def _sensor(self, rid: str, kind: str, first) -> _Sensor | None:
        s = self._sensors.get(rid)
        if s is None:
            if len(self._sensors) >= MAX_SENSORS:
                self.stats["report_sensors_over_limit"] += 1
                return None
            s = self._sensors[rid] = _Sensor(rid, first.sac, first.sic, kind, first)
            mark = self._cycle_marks.get(rid)
            if mark is not None:
                s.cycled, s.last_cycle, s.start = True, mark, mark
            if kind != ADSB and rid not in self.input_sites:
                self.note(
                    f"{kind} sensor {rid} has no site: its positions are relative to it; add "
                    f"[[radar]] sac = {first.sac}, sic = {first.sic}, lat, lon, alt to the "
                    "sites file"
                )
        if s.kind != kind:
            self.stats["report_kind_mixed"] += 1
            return None
        return s

    def _cycle(self, rid: str, t: int, out: list) -> None:
        """A start-of-update-cycle message: the open batch of ``rid`` ends at ``t``."""
        s = self._sensors.get(rid)
        if s is None:
            if len(self._cycle_marks) < MAX_SENSORS or rid in self._cycle_marks:
                self._cycle_marks[rid] = t
            return
        if s.last_cycle is not None and t > s.last_cycle:
            s.periods.append(t - s.last_cycle)
        if s.cycled or s.reports:
            self._emit(s, t, out, empty_ok=s.cycled)
        s.cycled, s.last_cycle, s.start = True, t, t

    def _add_report(self, s: _Sensor, r, out: list) -> None:
        t = r.time_ns
        if s.cycled and s.last_cycle is not None and t - s.last_cycle > self._lost_after(s):
            self.stats["report_cycles_lost"] += 1
            if s.reports:
                self._emit(s, max(x.time_ns for x in s.reports), out)
            s.cycled, s.window_end = False, None
        if not s.cycled:
            if s.window_end is not None and t >= s.window_end and s.reports:
                self._emit(s, s.window_end, out)
            if s.window_end is None or t >= s.window_end:
                s.window_end = (t // self.window_ns + 1) * self.window_ns
                s.start = s.window_end - self.window_ns
        key = _target_key(r)
        if key is not None and key in s.keys:
            self.stats["report_batch_split"] += 1
            self._emit(s, max(x.time_ns for x in s.reports), out)
        s.reports.append(r)
        if key is not None:
            s.keys.add(key)
        if len(s.reports) >= MAX_REPORTS_PER_BATCH:
            self.stats["report_batch_full"] += 1
            self._emit(s, max(x.time_ns for x in s.reports), out)

    def _lost_after(self, s: _Sensor) -> float:
        period = float(np.median(s.periods)) if s.periods else 1e9
        return CYCLES_LOST_AFTER * period

    # ------------------------------------------------------------------ output
    def _emit(self, s: _Sensor, end: int, out: list, empty_ok: bool = False) -> None:
        """The open batch of ``s`` ending at ``end`` (ns) as a PlotBatch."""
        reports = sorted(s.reports, key=lambda r: r.time_ns)
        s.reports, s.keys = [], set()
        site = self.site_of(s)
        kind = site.kind if site is not None else _geometry_of(s.first)
        reports = [r for r in reports if self._has_geometry(r, kind)]
        if not reports and not empty_ok:
            s.start = end
            return
        start = end if s.start is None else s.start
        if end < start:  # a cycle message timed before the batch began (clock step, corruption)
            self.stats["report_cycle_time_backwards"] += 1
            start = end
        if reports:
            start = min(start, reports[0].time_ns)
            end = max(end, reports[-1].time_ns)
        batch, reports = self._valid_batch(s, kind, site, start, end, reports)
        out.append((batch, [_report_type(r) for r in reports]))
        self.stats["report_batches"] += 1
        self.stats["report_plots"] += len(reports)
        s.plots += len(reports)
        s.seq += 1
        s.start = end

    def _valid_batch(self, s: _Sensor, kind, site, start: int, end: int, reports: list):
        """The PlotBatch of ``reports`` and the reports it holds. A report the wire
        contract refuses (a value outside its range, e.g. a velocity beyond 2000 m/s from
        a corrupted I202) is dropped and counted (``report_invalid``, the contract's
        message noted: field, value, why); the batch keeps the others."""
        try:
            return self._batch(s, kind, site, start, end, reports), reports
        except ValidationError:
            pass
        kept = []
        for r in reports:
            try:
                self._batch(s, kind, site, start, end, [r], Counter())
                kept.append(r)
            except ValidationError as exc:
                self.stats["report_invalid"] += 1
                if self.stats["report_invalid"] <= 3:
                    detail = exc.errors()[0]["msg"] if exc.errors() else str(exc)
                    self.note(f"{s.radar_id}: report dropped: {detail}")
        return self._batch(s, kind, site, start, end, kept), kept

    def _batch(self, s, kind, site, start, end, reports, stats=None) -> PlotBatch:
        """A batch's PlotBatch; the columns' counts go to ``stats`` (the reader's) only
        when the wire contract accepts it."""
        tally: Counter = Counter()
        cols = _columns(s.kind, kind, reports, site, self.adsb_sigma, tally)
        batch = PlotBatch(
            radar_id=s.radar_id, scan=s.seq, seq=s.seq, time_start=start, time_end=end,
            time=[r.time_ns for r in reports], **cols,
        )  # fmt: skip
        (self.stats if stats is None else stats).update(tally)
        return batch

    def _has_geometry(self, r, kind: RadarKind) -> bool:
        ok = {
            RadarKind.CARTESIAN: getattr(r, "x_m", None) is not None,
            RadarKind.WGS84: r.lat is not None,
        }.get(kind, getattr(r, "rho_m", None) is not None)
        if not ok:
            self.stats["report_no_position_for_kind"] += 1
        elif isinstance(r, cat021.Cat021Report) and r.sigma_pos_m is None:
            if self.adsb_sigma is None:
                self.stats["adsb_no_accuracy"] += 1
                return False
        return ok

    # ------------------------------------------------------------------ sites
    @property
    def sensors(self) -> dict[str, int]:
        """Sensor id → plots emitted so far."""
        return {rid: s.plots for rid, s in sorted(self._sensors.items())}

    def sources(self) -> dict[str, str]:
        """Sensor id → where its cycle period comes from (``sites``, ``cycle``,
        ``window``)."""
        out = {}
        for rid, s in self._sensors.items():
            site = self.input_sites.get(rid)
            given = site is not None and "scan_period" in site.model_fields_set
            out[rid] = "sites" if given else ("cycle" if s.periods else "window")
        return out

    def sites(self) -> dict[str, RadarSite]:
        """The site of every sensor seen that has one (module docstring)."""
        return {rid: site for rid, s in self._sensors.items() if (site := self.site_of(s))}

    def site_of(self, s: _Sensor) -> RadarSite | None:
        base = self.input_sites.get(s.radar_id)
        if base is None and s.kind == ADSB:
            base = self._adsb_anchor(s)
        if base is None:
            return None
        given = base.model_fields_set
        update = {k: v for k, v in SENSOR_DEFAULTS[s.kind].items() if k not in given}
        if "kind" not in given:
            update["kind"] = _geometry_of(s.first)
        if s.kind == SMR and "max_altitude" not in given:
            update["max_altitude"] = base.alt + SMR_CEILING_M
        if "scan_period" not in given:
            period = np.median(s.periods) * 1e-9 if s.periods else self.window_ns * 1e-9
            update["scan_period"] = float(min(max(period, 0.01), 600.0))
        if not update:
            return base
        return RadarSite(**{**base.model_dump(exclude_unset=True), **update})

    def _adsb_anchor(self, s: _Sensor) -> RadarSite | None:
        """An ADS-B sensor's site without a table: at its SAC/SIC's other site, else at
        its first report (module docstring); none while that report has no WGS-84
        position (a CAT010 TYP 2 report with I042 only)."""
        other = self.input_sites.get(radar_id_for(s.sac, s.sic))
        if other is None and s.first.lat is None:
            return None
        lat, lon, alt = (
            (other.lat, other.lon, other.alt) if other else (s.first.lat, s.first.lon, 0.0)
        )
        return RadarSite(radar_id=s.radar_id, name=f"ADS-B SAC {s.sac} SIC {s.sic}", lat=lat,
                         lon=lon, alt=alt)  # fmt: skip


def _position_free(r) -> bool:
    return r.lat is None and getattr(r, "x_m", None) is None and getattr(r, "rho_m", None) is None


def _target_key(r):
    """The sensor's own target key: its track number, else the address (a target reports
    once per batch)."""
    if r.track_number is not None:
        return ("track", r.track_number)
    address = r.address if isinstance(r, cat021.Cat021Report) else r.mode_s
    return None if address is None else ("address", address)


def _report_type(r) -> int:
    """The I020 TYP of a report (CAT020: 1, Mode S multilateration; CAT021: 2, ADS-B)."""
    if isinstance(r, cat010.Cat010Report):
        return -1 if r.typ is None else r.typ
    return ADSB_TYPE if isinstance(r, cat021.Cat021Report) else 1


def _geometry_of(r) -> RadarKind:
    """The plot geometry a sensor's first report gives: I042 cartesian, else WGS-84, else
    polar."""
    if getattr(r, "x_m", None) is not None:
        return RadarKind.CARTESIAN
    if r.lat is not None:
        return RadarKind.WGS84
    return RadarKind.TWO_D


def _columns(kind: str, geometry: RadarKind, reports: list, site, adsb_sigma, stats) -> dict:
    """The PlotBatch columns of a batch's reports (module docstring); none for an empty
    batch."""
    if not reports:
        return {}
    cols: dict[str, list] = {}
    if geometry is RadarKind.CARTESIAN:
        cols["x"] = [r.x_m for r in reports]
        cols["y"] = [r.y_m for r in reports]
    elif geometry is RadarKind.WGS84:
        cols["lat"] = [r.lat for r in reports]
        cols["lon"] = [r.lon for r in reports]
    else:
        cols["range"] = [r.rho_m for r in reports]
        cols["azimuth"] = [math.radians(r.theta_deg) % (2 * math.pi) for r in reports]
    if kind == SMR:
        if geometry is RadarKind.TWO_D and site is not None:
            cols["altitude"] = [float(site.alt)] * len(reports)
        if site is not None and any(r.length_m for r in reports):
            cols["sigma"] = [_extent_sigma(r, site) for r in reports]
        return cols
    cols["altitude"] = [_altitude(r, stats) for r in reports]
    cols["sigma"] = [_sigma(r, adsb_sigma) for r in reports]
    cols.update(_velocity(reports))
    cols.update(_identity(reports, stats))
    return cols


def _extent_sigma(r, site) -> float | None:
    """An SMR plot's σ per axis with its target's extent: the echo's centroid, while the
    other sensors report the aircraft's antenna, anywhere along its length L (I270):
    √(σ_c² + L²/12) (module docstring); null without a length."""
    if not r.length_m:
        return None
    return math.sqrt(site.sigma_cartesian**2 + r.length_m**2 / 12.0)


def _altitude(r, stats) -> float | None:
    """The geometric height when reported, else the flight level as a height (m)."""
    h = getattr(r, "geometric_height_m", None)
    if h is None:
        h = getattr(r, "height_m", None)
    if h is not None and -1000.0 <= h <= 100_000.0:
        return float(h)
    fl = r.flight_level
    if fl is None:
        return None
    if not ALTITUDE_FL[0] <= fl <= ALTITUDE_FL[1]:
        stats["report_flight_level_out_of_range"] += 1
        return None
    return fl * 100.0 * FT


def _sigma(r, adsb_sigma) -> float | None:
    """Horizontal σ per axis, m: ADS-B from its quality (or ``adsb_sigma``), a
    multilateration report from its I500 (null without)."""
    if isinstance(r, cat021.Cat021Report):
        s = adsb_sigma if adsb_sigma is not None else r.sigma_pos_m
    elif r.sigma_x_m is not None and r.sigma_y_m is not None:
        s = math.sqrt(0.5 * (r.sigma_x_m**2 + r.sigma_y_m**2))
    else:
        return None
    return None if s is None else max(float(s), 0.01)


def _velocity(reports: list) -> dict[str, list]:
    """v_east/v_north (and ADS-B's σ) when any report of the batch has a velocity."""
    if isinstance(reports[0], cat021.Cat021Report):
        ve = [r.v_east_ms for r in reports]
        vn = [r.v_north_ms for r in reports]
        sv = [r.sigma_vel_ms for r in reports]
    else:
        ve = [r.vx_ms for r in reports]
        vn = [r.vy_ms for r in reports]
        sv = [None] * len(reports)
    both = [(a, b) if a is not None and b is not None else (None, None) for a, b in zip(ve, vn)]
    if all(a is None for a, _ in both):
        return {}
    out = {"v_east": [a for a, _ in both], "v_north": [b for _, b in both]}
    if any(s is not None for s in sv):
        out["sigma_velocity"] = [None if s is None or s <= 0 else s for s in sv]
    return out


def _identity(reports: list, stats) -> dict[str, list]:
    """mode_s, mode_3a, callsign, flight_level, flight_status (ground bit)."""
    adsb = isinstance(reports[0], cat021.Cat021Report)
    mode_s = [r.address if adsb else r.mode_s for r in reports]
    callsign = []
    for r in reports:
        c = r.callsign
        if c is not None and not CALLSIGN_RE.match(c):
            stats["report_bad_callsign"] += 1
            c = None
        callsign.append(c)
    fl = [
        r.flight_level
        if r.flight_level is not None and FLIGHT_LEVEL_MIN <= r.flight_level <= FLIGHT_LEVEL_MAX
        else None
        for r in reports
    ]
    return {
        "mode_s": mode_s,
        "mode_3a": [r.mode_3a for r in reports],
        "callsign": callsign,
        "flight_level": fl,
        "flight_status": [1 if r.ground else None for r in reports],
    }
