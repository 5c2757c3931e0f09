"""ASTERIX CAT048/CAT034 → :class:`schemas.PlotBatch` sector batches and radar sites.

Pipeline: datagram (pcap UDP payload or raw file) → data blocks
(:func:`pcap.split_datablocks`) → records (split with the layout compiled from
libasterix's specification, :mod:`.layout`; libasterix itself parses any record the
fast path declines and reports the error) → plots and service messages → per-radar
sector batches.

Conversions (CAT048 item → PlotBatch column):

* radar id: I010 SAC/SIC → ``"{SAC}-{SIC}"`` (see :mod:`.sites`).
* time: I140 time of day (LSB 1/128 s) + a date → integer ns UTC. The date is the
  ``date`` argument when given; otherwise, for pcap, the capture timestamp (the day
  that puts the record within 12 h of its capture time); otherwise today (UTC). With a
  fixed date, midnight roll-over is detected when the time of day drops by more than
  12 h (next day); a record more than 12 h *ahead* of the last one is a late record
  from before midnight.
* range: I040 RHO (LSB 1/256 NM) × 1852 m/NM, slant range, m.
* azimuth: I040 THETA (LSB 360/2^16 deg) → rad clockwise from north.
* altitude: I090 flight level (LSB 1/4 FL) × 100 ft × 0.3048 m/ft. A flight level is a
  *pressure* altitude (ISA, 1013.25 hPa); it is used as the height above the ellipsoid,
  which is off by the QNH deviation (≈ 8 m/hPa, typically < 300 m) and the geoid
  undulation (< 100 m). Only validated, ungarbled codes (V = 0, G = 0) are kept;
  otherwise ``null`` (the converter then assigns an assumed altitude).
* ``mode_s``: I220 24-bit address; ``mode_3a``: I070 code as the integer of its 12 bits
  (octal 7777 → 4095), with its V, G and L bits as ``mode_3a_not_validated``,
  ``mode_3a_garbled`` and ``mode_3a_smoothed``; ``flight_level``: I090 as replied (FL),
  with V and G as ``flight_level_not_validated`` and ``flight_level_garbled``; ``spi``:
  I020 SPI; ``flight_status``: I230 STAT; ``callsign``: I240 (else a BDS 2,0 register
  of I250), padding removed, a value with characters outside the ICAO set dropped and
  counted (``cat048_bad_callsign``); the downlinked parameters: I250 registers BDS 4,0,
  5,0 and 6,0 decoded with pyModeS (:mod:`.bds`; counts ``cat048_bds_*``; without
  pyModeS ``cat048_bds_not_decoded_no_pymodes``). Every batch with plots carries all of
  these columns (null where a plot has no value), so consecutive batches of a radar
  have the same columns. Attributes for evaluation and display; never used by the
  tracker to associate.
* ``amplitude``: I130 PAM (primary plot amplitude, dBm), else SAM (SSR), when present.
* plot type: I020 TYP is returned beside each batch (``AsterixReadResult.plot_types``;
  ``PlotBatch`` has no plot-type column). TYP 0 ("no detection") and test targets
  (TST = 1) are skipped and counted; simulated reports (SIM = 1) are kept unless
  ``skip_simulated``.

Batches (one per radar sector):

* With CAT034: each sector crossing (I020 azimuth, LSB 360/2^8 deg) or North marker
  (azimuth 0) is a sector boundary; a radar's first boundary only opens its first
  sector. Boundaries are kept in time order (a North marker may overtake the last
  crossings); a second boundary at the same azimuth within half a scan (North marker +
  sector-0 crossing) is ignored. Each closed sector becomes a batch, even an empty one
  (a sector swept without detections is information for existence-based trackers).
  ``scan`` increments after the sector that ends at north. I041 gives the scan period,
  I120 the site position.
* Without CAT034 (per radar, until its first CAT034 message): fixed azimuth sectors of
  2π/``sector_count``; a plot in a later sector closes the open one (and the sectors
  skipped, as empty batches; with one sector per turn, a plot past north), with
  boundary times interpolated in azimuth between the last plot and the new one; a plot
  up to half a turn *behind* arriving within a quarter of a scan is a late plot of the
  open sector. The scan period is then estimated from the plots
  (:func:`.scan_period.estimate_scan_period`).
* Plots go to sectors by their *time* (time of day), not by arrival: a batch holds the
  plots timed after the previous boundary and up to its own. A closed sector is kept
  open for late plots for ``max_plot_delay`` seconds of the radar's own time (some
  radars deliver plots seconds after the sector message); plots arriving even later go
  into the next batch and are counted as ``late_plots``.
* ``time_start``/``time_end`` are the boundary times, widened to cover the batch's plot
  times; plots are sorted by time inside a batch; per radar, ``seq`` counts batches.

Bad input never raises: unknown categories, malformed blocks and records, and plots
that cannot be used are counted by reason in ``stats`` and described (first 200) in
``messages``; the rest of the input is still used. Exact duplicate records (the same
CAT and bytes within the last 4096 records, e.g. a capture of both lines of a
redundant A/B feed) are dropped and counted as ``duplicate_records`` unless
``dedup=False``.
"""

from __future__ import annotations

import bisect
import datetime as dt
import math
from collections import Counter, OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from skyfuse.schemas import PlotBatch, RadarKind, RadarSite
from skyfuse.schemas.identity import CALLSIGN_RE, DOWNLINKED

from . import bds, cat034, cat048, surveillance
from .pcap import Datagram, iter_file_datagrams, split_datablocks
from .record_reject import RecordReject
from .records import RecordError, iter_records
from .report_batches import ReportBatcher
from .scan_period import estimate_scan_period
from .sites import radar_id_for

NM = 1852.0
FT = 0.3048
DAY_NS = 86_400 * 1_000_000_000
HALF_DAY_S = 43_200.0
TWO_PI = 2.0 * math.pi
DEFAULT_SCAN_PERIOD_S = 4.0
MAX_MESSAGES = 200
DEDUP_WINDOW = 4096
MAX_PERIOD_SAMPLES = 20_000
IGNORED_CATEGORIES = frozenset({62, 63, 65})
MAX_PENDING_REPORTS = 100_000
ALTITUDE_FL = (-30.0, 3000.0)
"""Flight levels used as altitudes (within PlotBatch ``altitude`` bounds, -1000 m to
100 km; I048/090's own range is -12 to 1270 FL)."""
SECONDARY_COLUMNS = (
    "mode_3a_not_validated", "mode_3a_garbled", "mode_3a_smoothed", "callsign",
    "flight_level", "flight_level_not_validated", "flight_level_garbled", "spi",
    "flight_status", *(q.name for q in DOWNLINKED),
)  # fmt: skip
"""The PlotBatch columns a CAT048 plot fills besides geometry, amplitude and codes."""
_DOWNLINKED = tuple(q.name for q in DOWNLINKED)
_NO_DOWNLINK = (None,) * len(DOWNLINKED)


def flight_level_to_altitude(fl: float) -> float:
    """Flight level (hundreds of feet, pressure altitude) → metres (ISA ≈ height)."""
    return fl * 100.0 * FT


def altitude_to_flight_level(alt_m: float) -> float:
    """Inverse of :func:`flight_level_to_altitude`."""
    return alt_m / (100.0 * FT)


class TimeOfDayResolver:
    """Time of day (s since midnight UTC) → ns since the Unix epoch.

    ``date`` fixes the day of the first record (roll-over detected from the time of
    day); without it the capture time of each datagram picks the day, and without
    either the current UTC date is used."""

    def __init__(self, date: dt.date | None = None) -> None:
        self.date = date
        self._base_ns: int | None = _midnight_ns(date) if date is not None else None
        self._day = 0
        self._last_tod: float | None = None

    def resolve(self, tod: float, recv_time_ns: int | None = None) -> int:
        tod_ns = round(tod * 1e9)
        if self.date is None and recv_time_ns is not None:
            t = recv_time_ns // DAY_NS * DAY_NS + tod_ns
            if t - recv_time_ns > DAY_NS // 2:
                t -= DAY_NS
            elif recv_time_ns - t > DAY_NS // 2:
                t += DAY_NS
            return max(t, 0)
        if self._base_ns is None:
            self._base_ns = _midnight_ns(dt.datetime.now(dt.UTC).date())
        day = self._day
        if self._last_tod is None:
            self._last_tod = tod
        elif tod < self._last_tod - HALF_DAY_S:
            self._day += 1
            day = self._day
            self._last_tod = tod
        elif tod > self._last_tod + HALF_DAY_S:
            day -= 1  # a late record from before midnight
        else:
            self._last_tod = tod
        return max(self._base_ns + day * DAY_NS + tod_ns, 0)


def _midnight_ns(date: dt.date) -> int:
    midnight = dt.datetime(date.year, date.month, date.day, tzinfo=dt.UTC)
    return int(midnight.timestamp()) * 1_000_000_000


@dataclass
class _Radar:
    radar_id: str
    sac: int
    sic: int
    mode: str = "fixed"  # "fixed" azimuth sectors or "cat034" boundaries
    scan: int = 0
    seq: int = 0
    e_az: float | None = None  # where the next batch to emit starts (last emitted end), rad
    e_t: int | None = None  # ... and when, ns
    bounds: list[tuple[int, float, float | None]] = field(default_factory=list)
    # ^ closed sector boundaries (time ns, azimuth rad, fixed width or None) not yet emitted
    cur_idx: int | None = None  # fixed mode: index of the open sector
    last_t: int | None = None  # latest plot time, ns
    last_az: float = 0.0
    # plots not yet emitted, sorted by time (ties in arrival order): ptimes[i] is the
    # time of pending[i] = (time ns, range m, azimuth rad, altitude, amplitude, mode_s,
    # mode_3a, typ, values of SECONDARY_COLUMNS)
    ptimes: list[int] = field(default_factory=list)
    pending: list[tuple] = field(default_factory=list)
    periods_041: list[float] = field(default_factory=list)
    est_t: list[float] = field(default_factory=list)
    est_az: list[float] = field(default_factory=list)
    est_cache: tuple[int, float | None] | None = None  # (samples used, estimate)
    position: tuple[float, float, float] | None = None
    plots: int = 0
    now: int = 0  # latest time seen from this radar (plot or boundary), ns

    def last_boundary(self) -> tuple[int | None, float | None]:
        if self.bounds:
            return self.bounds[-1][0], self.bounds[-1][1]
        return self.e_t, self.e_az


@dataclass
class AsterixReadResult:
    """What :func:`read_asterix` found.

    ``batches``: sector batches of all radars, ordered by ``time_end``;
    ``plot_types``: I048/020 TYP per plot, parallel to ``batches`` (same plot order);
    ``sites``: radar id → RadarSite for every radar with a known position (sites file,
    else CAT034 I120), scan period filled in (see ``scan_period_source``);
    ``scan_period_source``: radar id → ``"sites"``, ``"cat034"``, ``"estimated"`` or
    ``"default"``; ``radars``: radar id → number of plots; ``stats``: counts by
    reason; ``messages``: the first problems in words."""

    batches: list[PlotBatch]
    plot_types: list[list[int]]
    sites: dict[str, RadarSite]
    scan_period_source: dict[str, str]
    radars: dict[str, int]
    stats: dict[str, int]
    messages: list[str]

    @property
    def n_plots(self) -> int:
        return sum(len(b) for b in self.batches)


class AsterixStreamDecoder:
    """Incremental CAT048/CAT034 decoder for a live UDP feed or a file.

    ``feed(datagram, recv_time_ns)`` returns the PlotBatches completed by that datagram
    (a sector closes at the next CAT034 boundary, or, without CAT034, when a plot
    arrives in a later fixed sector). ``flush()`` closes every open sector.
    ``recv_time_ns`` (ns UTC) picks the date unless ``date`` is given.

    ``sites``: radar id → RadarSite from a sites file (optional). ``sector_count``:
    fixed sectors per revolution when a radar sends no CAT034. ``max_plot_delay`` (s):
    how long a closed sector is held for plots that arrive after its boundary message
    but are timed before it (some radars deliver plots seconds late); plots are
    assigned to sectors by *time*, and a plot arriving after its sector was emitted
    goes into the next batch and is counted as ``late_plots``. 0 = emit at once.
    ``fast``: split CAT048 records with the compiled layout (:mod:`.layout`) instead of
    building libasterix objects for each (same values, ~20× faster).

    CAT010/CAT020/CAT021 blocks go to :class:`.surveillance.SurveillanceDecoder`
    (``cat021_edition``: ``"auto"`` or an edition name); their reports are handed to
    ``report_sink`` when given, else kept for :meth:`take_reports` (at most
    ``MAX_PENDING_REPORTS``; older ones are dropped and counted as ``reports_dropped``).
    With ``report_batches`` (default) they also become the PlotBatches of their sensors
    (multilateration, SMR, ADS-B: :mod:`.report_batches`, ``report_window`` s for sensors
    without cycle messages, ``adsb_sigma`` m an empirical σ of every ADS-B report),
    returned by :meth:`feed` beside the radars' sector batches."""

    def __init__(
        self,
        *,
        date: dt.date | None = None,
        sites: dict[str, RadarSite] | None = None,
        sector_count: int = 16,
        dedup: bool = True,
        skip_simulated: bool = False,
        max_plot_delay: float = 0.0,
        fast: bool = True,
        cat021_edition: str = "auto",
        report_sink: Callable[[surveillance.Report], None] | None = None,
        report_batches: bool = True,
        report_window: float = 1.0,
        adsb_sigma: float | None = None,
    ) -> None:
        self.fast = fast
        if not max_plot_delay >= 0.0:
            raise ValueError(f"max_plot_delay = {max_plot_delay} s: must be >= 0")
        self._hold_ns = max_plot_delay * 1e9
        if not 1 <= sector_count <= 360:
            raise ValueError(f"sector_count = {sector_count}: must be in 1..360")
        self.clock = TimeOfDayResolver(date)
        self.input_sites = dict(sites or {})
        self.sector_count = sector_count
        self.dedup = dedup
        self.skip_simulated = skip_simulated
        self.stats: Counter = Counter()
        self.messages: list[str] = []
        self._radars: dict[str, _Radar] = {}
        self._recent: OrderedDict[bytes, None] = OrderedDict()
        self._datagrams = 0
        self.surveillance = surveillance.SurveillanceDecoder(
            stats=self.stats,
            note=self._note,
            resolve=self.clock.resolve,
            is_duplicate=self._is_duplicate,
            cat021_edition=cat021_edition,
            fast=fast,
        )
        self._reports: deque[surveillance.Report] = deque()
        self._report_sink = report_sink
        self.batcher = (
            ReportBatcher(
                sites=self.input_sites, stats=self.stats, note=self._note, window=report_window,
                adsb_sigma=adsb_sigma, skip_simulated=skip_simulated,
            )
            if report_batches
            else None
        )  # fmt: skip

    # ---------------------------------------------------------------- public API
    def feed(self, datagram: bytes, recv_time_ns: int | None = None) -> list[PlotBatch]:
        """Decode one UDP datagram (one or more data blocks)."""
        return [b for b, _ in self.feed_with_types(Datagram(bytes(datagram), recv_time_ns))]

    def flush(self) -> list[PlotBatch]:
        """Close every radar's open sector (end of file / feed stopped)."""
        return [b for b, _ in self.flush_with_types()]

    def feed_with_types(self, dgram: Datagram) -> list[tuple[PlotBatch, list[int]]]:
        """Like :meth:`feed` for a :class:`Datagram`, with each batch's I020 TYP list."""
        self._datagrams += 1
        out: list[tuple[PlotBatch, list[int]]] = []
        where = f"datagram {self._datagrams}" + (f" ({dgram.source})" if dgram.source else "")
        for cat, data in split_datablocks(dgram.payload, self.stats, raw_stream=dgram.raw_stream):
            if cat == cat048.CATEGORY:
                self._cat048_block(data, dgram.time_ns, out, where)
            elif cat == cat034.CATEGORY:
                self._cat034_block(data, dgram.time_ns, out, where)
            elif cat in surveillance.CATEGORIES:
                reports = self.surveillance.decode_block(cat, data, dgram.time_ns, where)
                self._keep_reports(reports)
                if self.batcher is not None:
                    for r in reports:
                        out.extend(self.batcher.add(r))
            elif cat in IGNORED_CATEGORIES:
                self.stats[f"ignored_category_{cat}"] += 1
            else:
                self.stats[f"unknown_category_{cat}"] += 1
                if self.stats[f"unknown_category_{cat}"] == 1:
                    self._note(f"{where}: category {cat} is not decoded: blocks skipped")
        self._emit_ready(out)
        return out

    def flush_with_types(self) -> list[tuple[PlotBatch, list[int]]]:
        out: list[tuple[PlotBatch, list[int]]] = []
        for radar in self._radars.values():
            while radar.bounds:
                t_b, az_b, w = radar.bounds.pop(0)
                self._emit(radar, az_b, t_b, out, width=w)
            if not radar.pending:
                continue
            if radar.e_az is None:
                radar.e_az = radar.pending[0][2]
            offsets = [(p[2] - radar.e_az) % TWO_PI for p in radar.pending]
            width = min(TWO_PI, max(offsets) + 1e-6)
            if radar.mode == "fixed":
                width = max(width, min(TWO_PI, TWO_PI / self.sector_count))
            end_t = radar.ptimes[-1]
            self._emit(radar, (radar.e_az + width) % TWO_PI, end_t, out, width=width)
        if self.batcher is not None:
            out.extend(self.batcher.flush())
        return out

    def current_sites(self) -> tuple[dict[str, RadarSite], dict[str, str]]:
        """Sites known now (sites file + CAT034 I120) with scan periods filled in, and the
        source of each scan period."""
        sites: dict[str, RadarSite] = {}
        source: dict[str, str] = {}
        for rid in sorted(set(self.input_sites) | set(self._radars)):
            period, src = self._scan_period(rid)
            site = self.input_sites.get(rid)
            radar = self._radars.get(rid)
            if site is None and radar is not None and radar.position is not None:
                lat, lon, hgt = radar.position
                site = RadarSite(
                    radar_id=rid,
                    name=f"SAC {radar.sac} SIC {radar.sic} (CAT034 I120)",
                    lat=lat,
                    lon=lon,
                    alt=min(max(hgt, -500.0), 10_000.0),
                    kind=RadarKind.TWO_D,
                )
            if site is None:
                continue
            if src != "sites" and period is not None:
                site = site.model_copy(update={"scan_period": min(max(period, 0.01), 600.0)})
            sites[rid] = site
            source[rid] = src
        if self.batcher is not None:
            sites.update(self.batcher.sites())
            source.update(self.batcher.sources())
        return sites, source

    def take_reports(self) -> list[surveillance.Report]:
        """The CAT010/CAT020/CAT021 reports decoded since the last call (file order)."""
        out = list(self._reports)
        self._reports.clear()
        return out

    def _keep_reports(self, reports: list[surveillance.Report]) -> None:
        if self._report_sink is not None:
            for r in reports:
                self._report_sink(r)
            return
        self._reports.extend(reports)
        over = len(self._reports) - MAX_PENDING_REPORTS
        if over > 0:
            self.stats["reports_dropped"] += over
            for _ in range(over):
                self._reports.popleft()

    @property
    def radars(self) -> dict[str, int]:
        """Radar (and report sensor) id → number of plots decoded so far."""
        out = {rid: r.plots for rid, r in self._radars.items()}
        if self.batcher is not None:
            out.update(self.batcher.sensors)
        return dict(sorted(out.items()))

    # ---------------------------------------------------------------- internals
    def _note(self, text: str) -> None:
        if len(self.messages) < MAX_MESSAGES:
            self.messages.append(text)

    def _is_duplicate(self, cat: int, raw: bytes) -> bool:
        if not self.dedup:
            return False
        key = bytes([cat]) + raw
        if key in self._recent:
            self.stats["duplicate_records"] += 1
            return True
        self._recent[key] = None
        if len(self._recent) > DEDUP_WINDOW:
            self._recent.popitem(last=False)
        return False

    def _radar(self, sac: int, sic: int) -> _Radar:
        rid = radar_id_for(sac, sic)
        radar = self._radars.get(rid)
        if radar is None:
            radar = self._radars[rid] = _Radar(rid, sac, sic)
        return radar

    def _period_guess_ns(self, radar: _Radar) -> float:
        if radar.periods_041:
            p = radar.periods_041[-1]
        elif radar.radar_id in self.input_sites:
            p = self.input_sites[radar.radar_id].scan_period
        else:
            p = DEFAULT_SCAN_PERIOD_S
        return p * 1e9

    def _scan_period(self, rid: str) -> tuple[float | None, str]:
        site = self.input_sites.get(rid)
        if site is not None and "scan_period" in site.model_fields_set:
            return site.scan_period, "sites"
        radar = self._radars.get(rid)
        if radar is not None and radar.periods_041:
            return float(np.median(radar.periods_041)), "cat034"
        if radar is not None and len(radar.est_t) >= 8:
            if radar.est_cache is None or radar.est_cache[0] != len(radar.est_t):
                est = estimate_scan_period(np.asarray(radar.est_t), np.asarray(radar.est_az))
                radar.est_cache = (len(radar.est_t), None if est is None else est[0])
            if radar.est_cache[1] is not None:
                return radar.est_cache[1], "estimated"
        return (site.scan_period if site is not None else None), "default"

    def _block_error(self, cat: int, err: RecordError, index: int, where: str) -> None:
        self.stats[f"cat{cat:03d}_malformed_record"] += 1
        self._note(
            f"{where}: CAT{cat:03d} block, record {index + 1}: {err}; "
            "the rest of the block is skipped"
        )

    def _cat048_block(self, data: bytes, recv_ns: int | None, out: list, where: str) -> None:
        """Records of one CAT048 block: the fast splitter (:mod:`.layout`) while records
        are well formed, libasterix for the rest of the block after the first record the
        fast path declines (it gives the authoritative error), or for all of it when
        ``fast`` is off."""
        pos, index, n = 0, 0, len(data)
        while self.fast and pos < n:
            fast = cat048.decode_fast(data, pos)
            if fast is None:
                break
            plot, end = fast
            self._cat048_plot(plot, data[pos:end], recv_ns, index, where)
            pos, index = end, index + 1
        if pos >= n:
            return
        for rec in iter_records(cat048.SPEC, data[pos:]):
            if isinstance(rec, RecordError):
                self._block_error(48, rec, index, where)
                return
            raw = rec.unparse().to_bytes()
            self._cat048_plot(cat048.decode_record(rec), raw, recv_ns, index, where)
            index += 1

    def _cat048_plot(
        self,
        plot: cat048.Cat048Plot | RecordReject,
        raw: bytes,
        recv_ns: int | None,
        index: int,
        where: str,
    ) -> None:
        self.stats["cat048_records"] += 1
        if self._is_duplicate(48, raw):
            return
        if isinstance(plot, RecordReject):
            self.stats[plot.reason] += 1
            if self.stats[plot.reason] <= 3:
                self._note(f"{where}: CAT048 record {index + 1} skipped: {plot.detail}")
            return
        if plot.tst:
            self.stats["cat048_test_target"] += 1
            return
        if plot.sim:
            self.stats["cat048_simulated"] += 1
            if self.skip_simulated:
                return
        self._add_plot(plot, recv_ns)

    def _add_plot(self, plot: cat048.Cat048Plot, recv_ns: int | None) -> None:
        radar = self._radar(plot.sac, plot.sic)
        t = self.clock.resolve(plot.tod, recv_ns)
        az = math.radians(plot.theta_deg) % TWO_PI
        if radar.mode == "cat034":
            last_t, _ = radar.last_boundary()
            if last_t is not None and t - last_t > max(3.0 * self._period_guess_ns(radar), 2e10):
                # CAT034 boundaries stopped: fixed sectors from here on.
                self.stats["cat034_boundaries_lost"] += 1
                self._note(f"radar {radar.radar_id}: CAT034 boundaries stopped; fixed sectors")
                radar.mode = "fixed"
                radar.cur_idx = None
        if radar.mode == "fixed":
            self._fixed_sector_advance(radar, t, az)
        alt = self._altitude(plot)
        row = (
            t,
            plot.rho_nm * NM,
            az,
            alt,
            plot.amplitude_dbm,
            plot.mode_s,
            plot.mode_3a,
            plot.typ,
            self._secondary(plot),
        )
        if not radar.ptimes or t >= radar.ptimes[-1]:
            radar.ptimes.append(t)
            radar.pending.append(row)
        else:
            pos = bisect.bisect_right(radar.ptimes, t)
            radar.ptimes.insert(pos, t)
            radar.pending.insert(pos, row)
        radar.plots += 1
        radar.now = max(radar.now, t)
        self.stats["plots"] += 1
        if radar.last_t is None or t >= radar.last_t:
            radar.last_t, radar.last_az = t, az
        if len(radar.est_t) < MAX_PERIOD_SAMPLES:
            radar.est_t.append(t * 1e-9)
            radar.est_az.append(az)

    def _altitude(self, plot: cat048.Cat048Plot) -> float | None:
        """The altitude (m) of a validated, ungarbled flight level within
        :data:`ALTITUDE_FL` (others: counted ``cat048_flight_level_out_of_range``)."""
        level = plot.flight_level
        if level is None or plot.flight_level_not_validated or plot.flight_level_garbled:
            return None
        if not ALTITUDE_FL[0] <= level <= ALTITUDE_FL[1]:
            self.stats["cat048_flight_level_out_of_range"] += 1
            return None
        return flight_level_to_altitude(level)

    def _secondary(self, plot: cat048.Cat048Plot) -> tuple:
        """The values of :data:`SECONDARY_COLUMNS` of one plot (its I250 registers
        decoded, counted by what happened to each)."""
        values: dict = {}
        if plot.registers:
            values, counts = bds.decode_registers(plot.registers, plot.mode_s)
            for key in counts:
                self.stats[f"cat048_{key}"] += 1
            if counts and self.stats["cat048_bds_not_decoded_no_pymodes"] == len(counts):
                self._note("CAT048 I250 (Mode S BDS registers) not decoded: pyModeS is not "
                           "installed (pip install 'skyfuse[modes]')")  # fmt: skip
        callsign = plot.callsign if plot.callsign is not None else values.get("callsign")
        if callsign is not None and not CALLSIGN_RE.match(callsign):
            self.stats["cat048_bad_callsign"] += 1
            callsign = None
        downlinked = _NO_DOWNLINK if not values else tuple(values.get(n) for n in _DOWNLINKED)
        return (
            plot.mode_3a_not_validated, plot.mode_3a_garbled, plot.mode_3a_smoothed, callsign,
            plot.flight_level, plot.flight_level_not_validated, plot.flight_level_garbled,
            plot.spi, plot.flight_status, *downlinked,
        )  # fmt: skip

    def _fixed_sector_advance(self, radar: _Radar, t: int, az: float) -> None:
        """Queue the fixed-sector boundaries the beam crossed before a plot at (t, az)."""
        n = self.sector_count
        w = TWO_PI / n
        idx = min(int(az / w), n - 1)
        if radar.cur_idx is None:
            radar.cur_idx = idx
            last_t, _ = radar.last_boundary()
            if last_t is None:
                radar.e_az, radar.e_t = idx * w, t
            else:  # coming from CAT034 mode: a boundary where this sector starts
                radar.bounds.append((max(last_t, t), idx * w, None))
            return
        assert radar.last_t is not None
        d = (idx - radar.cur_idx) % n
        gap = t - radar.last_t
        period = self._period_guess_ns(radar)
        total = (az - radar.last_az) % TWO_PI
        first = ((radar.cur_idx + 1) * w - radar.last_az) % TWO_PI
        # one sector per turn: the beam moved on (less than half a turn) past the start
        wrapped = d == 0 and gap <= 0.5 * period and total < math.pi and 0 < first <= total
        if d == 0 and gap <= 0.5 * period and not wrapped:
            return
        if d > n // 2 and gap < 0.25 * period:
            return  # a late plot of the open sector
        if d == 0:
            d = n  # a whole revolution without plots, or (wrapped) the next one begun
        if first > total or (d == n and not wrapped):
            total += TWO_PI * max(1, round(gap / period - total / TWO_PI))
        last_t, _ = radar.last_boundary()
        for k in range(d):
            frac = min(max((first + k * w) / total, 0.0), 1.0) if total > 0 else 1.0
            t_k = max(radar.last_t + round(frac * gap), last_t or 0)
            radar.cur_idx = (radar.cur_idx + 1) % n
            radar.bounds.append((t_k, radar.cur_idx * w, w))
            last_t = t_k
        radar.cur_idx = idx

    def _cat034_block(self, data: bytes, recv_ns: int | None, out: list, where: str) -> None:
        """Records of one CAT034 block (fast path first, as for CAT048)."""
        pos, index, n = 0, 0, len(data)
        while self.fast and pos < n:
            fast = cat034.decode_fast(data, pos)
            if fast is None:
                break
            msg, end = fast
            self._cat034_message(msg, data[pos:end], recv_ns)
            pos, index = end, index + 1
        if pos >= n:
            return
        for rec in iter_records(cat034.SPEC, data[pos:]):
            if isinstance(rec, RecordError):
                self._block_error(34, rec, index, where)
                return
            raw = rec.unparse().to_bytes()
            self._cat034_message(cat034.decode_record(rec), raw, recv_ns)
            index += 1

    def _cat034_message(
        self, msg: cat034.Cat034Message | str, raw: bytes, recv_ns: int | None
    ) -> None:
        self.stats["cat034_records"] += 1
        if self._is_duplicate(34, raw):
            return
        if isinstance(msg, str):
            self.stats[msg] += 1
            return
        radar = self._radar(msg.sac, msg.sic)
        if msg.period_s is not None and msg.period_s > 0:
            radar.periods_041.append(msg.period_s)
            del radar.periods_041[:-64]  # the latest 64 revolutions
        if msg.lat is not None and msg.lon is not None and msg.height is not None:
            radar.position = (msg.lat, msg.lon, msg.height)
        if msg.message_type == cat034.NORTH_MARKER:
            self.stats["cat034_north_markers"] += 1
            az = 0.0
        elif msg.message_type == cat034.SECTOR_CROSSING:
            self.stats["cat034_sector_crossings"] += 1
            if msg.sector_deg is None:
                self.stats["cat034_sector_without_azimuth"] += 1
                return
            az = math.radians(msg.sector_deg) % TWO_PI
        else:
            self.stats[f"cat034_message_type_{msg.message_type}"] += 1
            return
        if msg.tod is not None:
            t = self.clock.resolve(msg.tod, recv_ns)
        elif radar.last_t is not None:
            t = radar.last_t
        else:
            self.stats["cat034_boundary_without_time"] += 1
            return
        self._boundary(radar, az, t)

    def _boundary(self, radar: _Radar, az: float, t: int) -> None:
        """Queue a CAT034 sector boundary (North marker = azimuth 0) in time order.

        Boundary messages can arrive out of order (a North marker overtaking the last
        sector crossings): they are sorted by their own time. A boundary older than the
        last emitted one is dropped (``cat034_late_boundary``); one at the same azimuth
        as its predecessor within half a scan is a repeat (``cat034_repeated_boundary``,
        e.g. a North marker and a sector-0 crossing)."""
        radar.mode = "cat034"
        radar.cur_idx = None
        if radar.e_t is not None and t < radar.e_t:
            self.stats["cat034_late_boundary"] += 1
            return
        if not radar.bounds or t >= radar.bounds[-1][0]:
            pos = len(radar.bounds)
        else:
            pos = bisect.bisect_right([b[0] for b in radar.bounds], t)
        half = 0.5 * self._period_guess_ns(radar)
        neighbours = []
        if pos > 0:
            neighbours.append(radar.bounds[pos - 1][:2])
        elif radar.e_t is not None and radar.e_az is not None:
            neighbours.append((radar.e_t, radar.e_az))
        if pos < len(radar.bounds):
            neighbours.append(radar.bounds[pos][:2])
        for nt, naz in neighbours:
            same = abs((az - naz + math.pi) % TWO_PI - math.pi) < 1e-6
            if same and abs(t - nt) < half:
                self.stats["cat034_repeated_boundary"] += 1
                return
        radar.bounds.insert(pos, (t, az, None))
        radar.now = max(radar.now, t)

    def _emit_ready(self, out: list) -> None:
        """Emit the batches whose end boundary is older than the plot delay allowance."""
        for radar in self._radars.values():
            while radar.bounds and radar.now - radar.bounds[0][0] >= self._hold_ns:
                t_b, az_b, w = radar.bounds.pop(0)
                self._emit(radar, az_b, t_b, out, width=w)

    def _emit(
        self, radar: _Radar, end_az: float, end_t: int, out: list, width: float | None = None
    ) -> None:
        """Emit the sector from the last emitted boundary to (end_az, end_t) with the plots
        timed up to ``end_t`` (plots older than the sector start are late: counted)."""
        n_take = bisect.bisect_right(radar.ptimes, end_t)
        take = radar.pending[:n_take]
        if radar.e_az is None and not take:
            radar.e_az, radar.e_t = end_az % TWO_PI, end_t  # the first boundary opens
            return
        if radar.e_az is None:  # the first sector of this radar: cover its plots
            w0 = width or TWO_PI / self.sector_count
            for row in take:
                w0 = max(w0, (end_az - row[2]) % TWO_PI + 1e-6)
            radar.e_az = (end_az - min(w0, TWO_PI)) % TWO_PI
        if width is None:
            width = (end_az - radar.e_az) % TWO_PI
            if width < 1e-9:
                width = TWO_PI
        width = min(max(width, 1e-9), TWO_PI)
        start_t = radar.e_t if radar.e_t is not None else end_t
        cols = list(zip(*take)) if take else [[]] * 9
        times = list(cols[0])
        if times:
            late = bisect.bisect_left(times, start_t)
            if late and radar.seq > 0:
                self.stats["late_plots"] += late
            start_t = min(start_t, times[0])
            end_t = max(end_t, times[-1])
        end_t = max(end_t, start_t)
        polar = bool(times)
        batch = PlotBatch(
            radar_id=radar.radar_id,
            scan=radar.scan,
            seq=radar.seq,
            sector_start=radar.e_az % TWO_PI,
            sector_width=width,
            time_start=start_t,
            time_end=end_t,
            time=times,
            range=list(cols[1]) if polar else None,
            azimuth=list(cols[2]) if polar else None,
            altitude=list(cols[3]) if polar else None,
            amplitude=list(cols[4]) if polar else None,
            mode_s=list(cols[5]) if polar else None,
            mode_3a=list(cols[6]) if polar else None,
            **(dict(zip(SECONDARY_COLUMNS, map(list, zip(*cols[8])))) if polar else {}),
        )
        out.append((batch, list(cols[7])))
        self.stats["batches"] += 1
        radar.seq += 1
        if radar.e_az + width >= TWO_PI - 1e-9:
            radar.scan += 1
        radar.e_az = end_az % TWO_PI
        radar.e_t = end_t
        del radar.ptimes[:n_take]
        del radar.pending[:n_take]


def read_asterix(
    path: str | Path,
    *,
    date: dt.date | None = None,
    sites: dict[str, RadarSite] | None = None,
    sector_count: int = 16,
    dedup: bool = True,
    skip_simulated: bool = False,
    max_plot_delay: float = 30.0,
    fast: bool = True,
    report_window: float = 1.0,
    adsb_sigma: float | None = None,
) -> AsterixReadResult:
    """Read a pcap or raw ASTERIX file into sector batches (see the module docstring) and
    the batches of its report-based sensors (CAT010/CAT020/CAT021:
    :mod:`.report_batches`).

    ``date``: UTC date of the first record (default: from the pcap capture times, else
    today). ``sites``: from :func:`.sites.load_sites`. Other arguments as for
    :class:`AsterixStreamDecoder` (a file can afford to wait ``max_plot_delay`` = 30 s
    of data for late plots). Raises only for an unreadable file
    or a pcapng container; bad ASTERIX content is counted in ``stats``."""
    decoder = AsterixStreamDecoder(
        date=date,
        sites=sites,
        sector_count=sector_count,
        dedup=dedup,
        skip_simulated=skip_simulated,
        max_plot_delay=max_plot_delay,
        fast=fast,
        report_window=report_window,
        adsb_sigma=adsb_sigma,
    )
    pairs: list[tuple[PlotBatch, list[int]]] = []
    for dgram in iter_file_datagrams(path, decoder.stats):
        pairs.extend(decoder.feed_with_types(dgram))
    pairs.extend(decoder.flush_with_types())
    pairs.sort(key=lambda p: (p[0].time_end, p[0].radar_id, p[0].seq))
    found_sites, source = decoder.current_sites()
    for rid in decoder.radars:
        if rid not in found_sites:
            decoder.stats["radars_without_site"] += 1
            if rid in decoder._radars:
                sac, sic = decoder._radars[rid].sac, decoder._radars[rid].sic
                decoder._note(
                    f"radar {rid} has no position (no sites entry, no CAT034 I120): add "
                    f"[[radar]] sac = {sac}, sic = {sic}, lat, lon, alt to the sites file"
                )
    return AsterixReadResult(
        batches=[b for b, _ in pairs],
        plot_types=[t for _, t in pairs],
        sites=found_sites,
        scan_period_source=source,
        radars=decoder.radars,
        stats=dict(decoder.stats),
        messages=list(decoder.messages),
    )


def merge_results(results: list[AsterixReadResult], names: list[str]) -> AsterixReadResult:
    """Several recordings (of different sensors: no radar id in two of them) as one:
    batches in ``(time_end, radar id, seq)`` order, sites and plots per radar joined,
    counts added, messages prefixed by the file ``names``. ValueError names a radar id
    two recordings share (its batches would interleave two numberings)."""
    owner: dict[str, str] = {}
    for res, name in zip(results, names):
        for rid in res.radars:
            if rid in owner:
                raise ValueError(f"sensor {rid} is in both {owner[rid]} and {name}")
            owner[rid] = name
    pairs = [(b, t) for res in results for b, t in zip(res.batches, res.plot_types)]
    pairs.sort(key=lambda p: (p[0].time_end, p[0].radar_id, p[0].seq))
    stats: Counter = Counter()
    sites: dict[str, RadarSite] = {}
    source: dict[str, str] = {}
    for res in results:
        stats.update(res.stats)
        # a sensor's own recording knows its site best (its cycle, its kind)
        sites.update({k: v for k, v in res.sites.items() if k not in sites or k in res.radars})
        source.update({k: v for k, v in res.scan_period_source.items() if k in res.radars})
    return AsterixReadResult(
        batches=[b for b, _ in pairs],
        plot_types=[t for _, t in pairs],
        sites=sites,
        scan_period_source=source,
        radars={rid: n for res in results for rid, n in res.radars.items()},
        stats=dict(stats),
        messages=[f"{name}: {m}" for res, name in zip(results, names) for m in res.messages],
    )
