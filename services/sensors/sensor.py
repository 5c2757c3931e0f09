"""A simulated radar as a network service: one radar of a scenario, in (scaled) real time.

The sensor runs the scenario simulator (:mod:`fusion.sim`) and publishes the events of
its radar: the ``RadarSite`` (as a message, as the answer of a queryable on its site key,
and as a liveliness token ``radar/{id}/alive``) and each sector ``PlotBatch`` when the
simulated beam leaves the sector. Message contents keep the simulated times (the
scenario's fixed epoch); the pacing maps simulated offsets to the wall clock::

    wall(t) = wall0 + (t - t0) / speed

and each PlotBatch carries ``wall(time_end)`` as its attachment
(:func:`services.transport.wall_stamp`), the instant the sweep ended on the wall clock,
from which the fusion service measures plot-to-track latency.

With ``truth`` the sensor also publishes the simulation truth (one sensor of a demo
does, so the recorder can store it for evaluation).
"""

from __future__ import annotations

import datetime as dt
import logging
import socket
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from pydantic import Field, field_validator
from skyfuse.schemas import PlotBatch, RadarSite, Status, keys
from skyfuse.services.cli.config import ConfigError
from skyfuse.services.cli.scenario_config import ScenarioSelection
from skyfuse.services.runtime.transport import (
    declare_liveliness,
    declare_publisher,
    service_alive_key,
    wall_stamp,
)

log = logging.getLogger(__name__)


class SensorConfig(ScenarioSelection):
    radar: str | None = Field(
        None,
        description="Radar id in the scenario (e.g. R1); with --asterix/--asterix-udp: only "
        "this radar (SAC-SIC, e.g. 25-201)",
    )
    speed: float = Field(1.0, gt=0, le=1000, description="Time scale: 10 = ten times faster")
    replay: Path | None = Field(None, description="Publish this radar's batches from an MCAP")
    asterix: Path | None = Field(
        None,
        description="Publish every radar of this ASTERIX CAT048/CAT034 recording (.pcap or raw "
        ".ast), paced by the plot times",
    )
    asterix_udp: str | None = Field(
        None,
        description="Receive a live ASTERIX CAT048/CAT034 UDP stream on HOST:PORT (e.g. "
        "127.0.0.1:30048) and publish each sector as it completes",
    )
    sites: Path | None = Field(
        None, description="ASTERIX sites TOML ([[radar]] sac, sic, lat, lon, alt, ...)"
    )
    date: dt.date | None = Field(
        None,
        description="ASTERIX: UTC date of the first record, YYYY-MM-DD (default: pcap capture "
        "time, else today)",
    )
    sector_count: int = Field(
        16, ge=1, le=360, description="ASTERIX: fixed sectors per turn for radars without CAT034"
    )
    max_plot_delay: float | None = Field(
        None,
        ge=0,
        le=60,
        description="ASTERIX: s a closed sector waits for late plots (default: 30 for a file, "
        "0 for --asterix-udp)",
    )
    truth: bool = Field(False, description="Also publish the simulation truth")
    wait_for: list[str] = Field(
        default_factory=list,
        description="Service names (e.g. fusion,recorder) to wait for before starting",
    )
    wait_timeout: float = Field(15.0, gt=0, description="How long to wait for them, s")
    start_at: float | None = Field(
        None,
        gt=0,
        description="Unix time (s) the scenario start maps to; sensors given the same value "
        "run in step (default: now)",
    )
    align: float | None = Field(
        None,
        gt=0,
        le=3600,
        description="Start at the next wall-clock multiple of this many s (>= 1 s ahead), "
        "after --wait-for: sensors started apart then run in step",
    )
    status_interval: float = Field(2.0, gt=0, description="Status publication period, s")
    linger: float = Field(
        0.5, ge=0, le=30, description="Seconds to stay connected after the last batch"
    )

    @field_validator("radar")
    @classmethod
    def _id(cls, v: str | None) -> str | None:
        return None if v is None else keys.check_id(v, "radar id")

    @field_validator("asterix_udp")
    @classmethod
    def _udp(cls, v: str | None) -> str | None:
        if v is not None:
            parse_host_port(v, "asterix_udp")
        return v

    @property
    def mode(self) -> str:
        """``simulate``, ``replay``, ``asterix`` or ``asterix-udp``."""
        if self.asterix is not None:
            return "asterix"
        if self.asterix_udp is not None:
            return "asterix-udp"
        return "replay" if self.replay is not None else "simulate"


def parse_host_port(text: str, what: str = "address") -> tuple[str, int]:
    """``HOST:PORT`` → (host, port); ``ValueError`` naming ``what`` if malformed."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) <= 65535:
        raise ValueError(f"{what} {text!r} is not HOST:PORT with a port in 1..65535")
    return host.strip("[]"), int(port)


def load_scenario(cfg: SensorConfig):
    """The scenario of ``cfg`` and this radar's site (``ConfigError`` if absent)."""
    sc = cfg.build_scenario()
    ids = [s.radar_id for s in sc.sites]
    if cfg.radar not in ids:
        raise ConfigError(
            f"radar {cfg.radar!r} is not in scenario {cfg.scenario!r}: its radars are "
            + ", ".join(ids)
        )
    return sc, sc.sites[ids.index(cfg.radar)]


def start_time_ns(cfg: SensorConfig, now_ns: int | None = None) -> int:
    """The wall-clock instant (ns) the scenario start maps to: ``start_at``, else the next
    multiple of ``align`` seconds at least 1 s ahead, else now."""
    now_ns = time.time_ns() if now_ns is None else now_ns
    if cfg.start_at is not None:
        return round(cfg.start_at * 1e9)
    if cfg.align is not None:
        step = round(cfg.align * 1e9)
        return -(-(now_ns + 1_000_000_000) // step) * step
    return now_ns


@dataclass
class SensorStats:
    published: Counter = field(default_factory=Counter)
    plots: int = 0
    late_s: float = 0.0
    """Worst lateness of a publication behind its due wall-clock time, s."""
    interrupted: bool = False


class SimulatedRadar:
    """Publishes one radar's site and plots from the scenario simulator."""

    def __init__(self, session, cfg: SensorConfig) -> None:
        self.session = session
        self.cfg = cfg
        self.scenario, self.site = load_scenario(cfg)
        self.stats = SensorStats()
        self._site_bytes = self.site.to_json_bytes()
        self._pub_site = declare_publisher(session, keys.radar_site(cfg.radar))
        self._pub_plots = declare_publisher(session, keys.radar_plots(cfg.radar))
        self._pub_truth = declare_publisher(session, keys.SIM_TRUTH) if cfg.truth else None
        self._pub_status = declare_publisher(session, keys.service_status(f"sensor-{cfg.radar}"))
        self._queryable = session.declare_queryable(keys.radar_site(cfg.radar), self._answer_site)
        self._token = None
        self._ready = declare_liveliness(session, service_alive_key(f"sensor-{cfg.radar}"))

    def _answer_site(self, query) -> None:
        query.reply(keys.radar_site(self.cfg.radar), self._site_bytes)

    def publish_site(self, site: RadarSite | None = None) -> None:
        if site is not None:
            self.site = site
            self._site_bytes = site.to_json_bytes()
        self._pub_site.put(self._site_bytes)
        self.stats.published["site"] += 1
        if self._token is None:
            self._token = declare_liveliness(self.session, keys.radar_alive(self.cfg.radar))

    def _status(self, t_start: float) -> None:
        st = Status(
            service="sensor",
            service_id=f"sensor-{self.cfg.radar}",
            time=time.time_ns(),
            uptime_s=time.monotonic() - t_start,
            counters={
                "batches": self.stats.published["plots"],
                "plots": self.stats.plots,
                "truth": self.stats.published["truth"],
            },
            message=f"late by up to {self.stats.late_s:.3f} s",
        )
        self._pub_status.put(st.to_json_bytes())

    def run(self, stop) -> SensorStats:
        """Publish until the scenario ends or ``stop`` is set."""
        from skyfuse.fusion.sim import Simulator

        cfg = self.cfg
        self.publish_site()
        start_ns = start_time_ns(cfg)
        if start_ns < time.time_ns() - 100_000_000:
            log.warning(
                "start time is %.2f s in the past: the first batches will be late",
                (time.time_ns() - start_ns) / 1e9,
            )
        wall0 = time.monotonic()
        t0 = getattr(self.scenario, "start_time", None)
        next_status = wall0
        for ev in Simulator(self.scenario, seed=cfg.seed).run():
            if ev.kind == "truth":
                if self._pub_truth is None:
                    continue
            elif getattr(ev.message, "radar_id", None) != cfg.radar:
                continue
            if t0 is None:
                t0 = ev.time
            due_ns = start_ns + int((ev.time - t0) / cfg.speed)
            delay = (due_ns - time.time_ns()) / 1e9
            if delay > 0 and stop.wait(delay):
                self.stats.interrupted = True
                break
            if stop.is_set():
                self.stats.interrupted = True
                break
            self.stats.late_s = max(self.stats.late_s, -delay)
            if ev.kind == "plots":
                self._pub_plots.put(ev.message.to_json_bytes(), attachment=wall_stamp(due_ns))
                self.stats.plots += len(ev.message.time)
                self.stats.published["plots"] += 1
            elif ev.kind == "site":
                if ev.message.to_json_bytes() != self._site_bytes:
                    self.publish_site(ev.message)
            else:
                self._pub_truth.put(ev.message.to_json_bytes())
                self.stats.published["truth"] += 1
            now = time.monotonic()
            if now >= next_status:
                next_status = now + cfg.status_interval
                self._status(wall0)
        self._status(wall0)
        return self.stats

    def close(self) -> None:
        if self._ready is not None:
            self._ready.undeclare()
            self._ready = None
        if self._token is not None:
            self._token.undeclare()
            self._token = None
        self._queryable.undeclare()


# ------------------------------------------------------------------------------------
# ASTERIX: a recording or a live UDP feed, every radar in it served by one process
# ------------------------------------------------------------------------------------
class RadarFleet:
    """Zenoh side of a sensor process that serves several radars (ASTERIX input).

    Per radar: a ``RadarSite`` message and a queryable on ``radar/{id}/site`` once its
    site is known, a liveliness token ``radar/{id}/alive`` from its first site or batch
    on, and its ``PlotBatch`` publications (BLOCK publishers). ``service`` names the
    process's own ready token and status key."""

    def __init__(self, session, service: str) -> None:
        self.session = session
        self.service = service
        self.sites: dict[str, bytes] = {}
        self.stats = SensorStats()
        self.batches_by_radar: Counter = Counter()
        self._pub_plots: dict[str, object] = {}
        self._pub_site: dict[str, object] = {}
        self._queryables: dict[str, object] = {}
        self._tokens: dict[str, object] = {}
        self._pub_status = declare_publisher(session, keys.service_status(service))
        self._ready = declare_liveliness(session, service_alive_key(service))

    def alive(self, radar_id: str) -> None:
        """Declare the radar's liveliness token (once)."""
        if radar_id not in self._tokens:
            self._tokens[radar_id] = declare_liveliness(self.session, keys.radar_alive(radar_id))

    def site(self, site: RadarSite) -> bool:
        """Publish ``site`` if it is new or changed; answer queries with it from now on."""
        rid = site.radar_id
        payload = site.to_json_bytes()
        if self.sites.get(rid) == payload:
            return False
        self.sites[rid] = payload
        if rid not in self._pub_site:
            self._pub_site[rid] = declare_publisher(self.session, keys.radar_site(rid))

            def answer(query, rid=rid) -> None:
                query.reply(keys.radar_site(rid), self.sites[rid])

            self._queryables[rid] = self.session.declare_queryable(keys.radar_site(rid), answer)
        self._pub_site[rid].put(payload)
        self.stats.published["site"] += 1
        self.alive(rid)
        return True

    def plots(self, batch: PlotBatch, stamp_ns: int) -> None:
        """Publish one batch with the wall-clock stamp ``stamp_ns`` as its attachment."""
        rid = batch.radar_id
        pub = self._pub_plots.get(rid)
        if pub is None:
            pub = self._pub_plots[rid] = declare_publisher(self.session, keys.radar_plots(rid))
            self.alive(rid)
        pub.put(batch.to_json_bytes(), attachment=wall_stamp(stamp_ns))
        self.stats.published["plots"] += 1
        self.stats.plots += len(batch)
        self.batches_by_radar[rid] += 1

    def status(self, t_start: float, counters: dict[str, int], message: str = "") -> None:
        st = Status(
            service="sensor",
            service_id=self.service,
            time=time.time_ns(),
            uptime_s=time.monotonic() - t_start,
            counters={
                "batches": self.stats.published["plots"],
                "plots": self.stats.plots,
                "radars": len(self._tokens),
                **counters,
            },
            message=message,
        )
        self._pub_status.put(st.to_json_bytes())

    def close(self) -> None:
        for handle in [
            self._ready,
            *self._tokens.values(),
            *self._queryables.values(),
            *self._pub_plots.values(),
            *self._pub_site.values(),
        ]:
            if handle is not None:
                handle.undeclare()
        self._ready = None
        self._tokens.clear()
        self._queryables.clear()
        self._pub_plots.clear()
        self._pub_site.clear()


def _asterix_sites(cfg: SensorConfig) -> dict[str, RadarSite] | None:
    if cfg.sites is None:
        return None
    from skyfuse.services.asterix import SitesError, load_sites

    try:
        return load_sites(cfg.sites)
    except (SitesError, OSError) as e:
        raise ConfigError(str(e)) from None


def _stats_text(stats: dict[str, int]) -> str:
    keep = ("plots", "batches", "duplicate_records", "late_plots", "radars_without_site")
    bad = {k: v for k, v in stats.items() if "malformed" in k or k.startswith("unknown_category")}
    return ", ".join(f"{k} {stats[k]}" for k in keep if stats.get(k)) + (
        f"; problems {bad}" if bad else ""
    )


class AsterixRecordingSensor:
    """Publishes every radar of an ASTERIX recording (``cfg.asterix``) on Zenoh.

    The file is decoded with :func:`services.asterix.read_asterix` (sites from
    ``cfg.sites``, else CAT034 I120); then the sites are published (message, queryable,
    liveliness token per radar) and the sector batches of all radars in ``time_end``
    order, paced as ``wall(t) = wall0 + (t − t0) / speed`` with ``t0`` the first batch's
    end. Each batch's attachment is ``wall(time_end)``. ``cfg.radar`` restricts the
    publication to one radar. Radars without a known position still publish batches and
    liveliness (the fusion service counts them as "no site for radar") and are named in
    the log, with the sites-file entry they need."""

    def __init__(self, session, cfg: SensorConfig) -> None:
        from skyfuse.services.asterix import read_asterix

        if not cfg.asterix.is_file():
            raise ConfigError(f"asterix {str(cfg.asterix)!r} does not exist")
        self.cfg = cfg
        delay = 30.0 if cfg.max_plot_delay is None else cfg.max_plot_delay
        self.result = read_asterix(
            cfg.asterix,
            date=cfg.date,
            sites=_asterix_sites(cfg),
            sector_count=cfg.sector_count,
            max_plot_delay=delay,
        )
        radars = set(self.result.radars)
        if cfg.radar is not None:
            if cfg.radar not in radars:
                raise ConfigError(
                    f"radar {cfg.radar!r} is not in {str(cfg.asterix)!r}: its radars are "
                    + (", ".join(sorted(radars)) or "none")
                )
            radars = {cfg.radar}
        self.radars = sorted(radars)
        self.batches = [b for b in self.result.batches if b.radar_id in radars]
        self.fleet = RadarFleet(session, f"sensor-{cfg.radar or 'asterix'}")

    def run(self, stop) -> SensorStats:
        cfg, res, fleet = self.cfg, self.result, self.fleet
        for rid in self.radars:
            site = res.sites.get(rid)
            if site is not None:
                fleet.site(site)
            else:
                log.warning("radar %s has no site: its batches cannot be tracked", rid)
            fleet.alive(rid)
        for text in res.messages[:10]:
            log.info("asterix: %s", text)
        log.info(
            "%s: %d radars (%s), %d batches; %s",
            cfg.asterix,
            len(self.radars),
            ", ".join(self.radars),
            len(self.batches),
            _stats_text(res.stats),
        )
        start_ns = start_time_ns(cfg)
        wall0 = time.monotonic()
        next_status = wall0
        t0 = self.batches[0].time_end if self.batches else 0
        for batch in self.batches:
            due_ns = start_ns + int((batch.time_end - t0) / cfg.speed)
            delay = (due_ns - time.time_ns()) / 1e9
            if delay > 0 and stop.wait(delay):
                fleet.stats.interrupted = True
                break
            if stop.is_set():
                fleet.stats.interrupted = True
                break
            fleet.stats.late_s = max(fleet.stats.late_s, -delay)
            fleet.plots(batch, due_ns)
            now = time.monotonic()
            if now >= next_status:
                next_status = now + cfg.status_interval
                fleet.status(wall0, {}, f"late by up to {fleet.stats.late_s:.3f} s")
        fleet.status(wall0, {}, f"late by up to {fleet.stats.late_s:.3f} s")
        return fleet.stats

    def close(self) -> None:
        self.fleet.close()


class AsterixUdpSensor:
    """Receives a live ASTERIX CAT048/CAT034 UDP stream and publishes its radars on Zenoh.

    Datagrams go to :class:`services.asterix.AsterixStreamDecoder` (sites from
    ``cfg.sites`` and CAT034 I120); each sector batch is published as soon as the
    decoder completes it (the next CAT034 boundary, or a plot in a later fixed sector,
    after ``max_plot_delay``), with the wall-clock receive time of the datagram that
    completed it as its attachment. A radar's liveliness token appears with its first
    batch; its site is published once known and again when it changes (scan period
    estimated from the plots, CAT034 I041/I120), checked about once a second. On stop
    the open sectors are flushed and published."""

    SITE_CHECK_S = 1.0

    def __init__(self, session, cfg: SensorConfig) -> None:
        from skyfuse.services.asterix import AsterixStreamDecoder

        self.cfg = cfg
        host, port = parse_host_port(cfg.asterix_udp, "asterix_udp")
        self.decoder = AsterixStreamDecoder(
            date=cfg.date,
            sites=_asterix_sites(cfg),
            sector_count=cfg.sector_count,
            max_plot_delay=0.0 if cfg.max_plot_delay is None else cfg.max_plot_delay,
        )
        try:
            info = socket.getaddrinfo(host, port, socket.AF_INET, socket.SOCK_DGRAM)
            self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
            self.sock.bind(info[0][4])
        except OSError as e:
            raise ConfigError(f"asterix_udp {cfg.asterix_udp!r}: cannot bind: {e}") from None
        self.sock.settimeout(0.1)
        self.address = self.sock.getsockname()
        self.datagrams = 0
        self.filtered = 0
        self._new_site_check = -1e9
        self._published: dict[str, RadarSite] = {}
        self.fleet = RadarFleet(session, f"sensor-{cfg.radar or 'asterix-udp'}")

    def _publish(self, batches: list[PlotBatch], stamp_ns: int) -> None:
        for b in batches:
            if self.cfg.radar is not None and b.radar_id != self.cfg.radar:
                self.filtered += 1
                continue
            self.fleet.plots(b, stamp_ns)

    def _sites(self) -> None:
        """Publish the sites of the radars heard so far: new ones, and changed ones — a
        scan period estimated from the plots only when it moved by more than 1 %."""
        sites, _ = self.decoder.current_sites()
        heard = self.decoder.radars
        for rid, site in sites.items():
            if self.cfg.radar is not None and rid != self.cfg.radar:
                continue
            if rid not in heard:
                continue
            old = self._published.get(rid)
            if old is not None:
                same = old.model_copy(update={"scan_period": site.scan_period}) == site
                if same and abs(site.scan_period - old.scan_period) <= 0.01 * old.scan_period:
                    continue
            if self.fleet.site(site):
                self._published[rid] = site

    def run(self, stop, duration: float | None = None) -> SensorStats:
        log.info("listening for ASTERIX on udp %s:%d", *self.address)
        wall0 = time.monotonic()
        next_sites = next_status = wall0
        while not stop.is_set():
            if duration is not None and time.monotonic() - wall0 >= duration:
                break
            try:
                data = self.sock.recv(65_535)
            except TimeoutError:
                data = None
            now_ns = time.time_ns()
            if data:
                self.datagrams += 1
                batches = self.decoder.feed(data, now_ns)
                new = {b.radar_id for b in batches} - set(self.fleet.sites)
                if new and time.monotonic() - self._new_site_check > 0.2:
                    self._new_site_check = time.monotonic()
                    self._sites()  # a new radar's site goes out before its first batch
                self._publish(batches, now_ns)
            now = time.monotonic()
            if now >= next_sites:
                next_sites = now + self.SITE_CHECK_S
                self._sites()
            if now >= next_status:
                next_status = now + self.cfg.status_interval
                self._status(wall0)
        self._sites()
        self._publish(self.decoder.flush(), time.time_ns())
        self._status(wall0)
        return self.fleet.stats

    def _status(self, wall0: float) -> None:
        st = self.decoder.stats
        self.fleet.status(
            wall0,
            {"datagrams": self.datagrams, **{k: v for k, v in st.items() if isinstance(v, int)}},
            _stats_text(dict(st)),
        )

    def close(self) -> None:
        self.sock.close()
        self.fleet.close()
