"""A sensor process receiving a live ASTERIX CAT048/CAT034 UDP feed and publishing each
sector as it completes (``skyfuse sensor --asterix-udp HOST:PORT``).

Times: I140 is a time of day. Without ``--date`` each record takes the UTC day that puts
it nearest (within 12 h) to the receive clock of its datagram — right for a live feed,
across midnight too. An old capture played into the port would then be stamped up to
12 h away from its real day: give ``--date`` (the UTC date of its first record). The
sensor warns once when the records are more than :data:`STALE_S` from the receive clock.
"""

from __future__ import annotations

import logging
import socket
import time

from skyfuse.schemas import PlotBatch, RadarSite
from skyfuse.services.runtime.config import ConfigError
from skyfuse.services.runtime.state_files import state_home
from skyfuse.services.sensors.config import SensorServiceConfig, SensorStats, parse_host_port
from skyfuse.services.sensors.continuation import SequenceCeiling
from skyfuse.services.sensors.fleet import RadarFleet, asterix_sites, stats_text

log = logging.getLogger(__name__)

STALE_S = 600.0
"""Records this far (s) from the receive clock get a warning: an old capture? --date."""


class AsterixUdpSensor:
    """Receives a live ASTERIX CAT048/CAT034 UDP stream and publishes its radars on Zenoh.

    Datagrams go to :class:`services.asterix.AsterixStreamDecoder` (sites from
    ``cfg.sites`` and CAT034 I120); each sector batch is published as soon as the
    decoder completes it (the next CAT034 boundary, or a plot in a later fixed sector,
    after ``max_plot_delay``), with the wall-clock receive time of the datagram that
    completed it as its attachment. A radar's liveliness token appears with its first
    batch; its site is published once known and again when it changes (scan period
    estimated from the plots, CAT034 I041/I120), checked about once a second. On stop
    the datagrams already received are read, then the open sectors are flushed and
    published."""

    SITE_CHECK_S = 1.0

    def __init__(self, session, cfg: SensorServiceConfig) -> None:
        from skyfuse.services.asterix import AsterixStreamDecoder

        self.cfg = cfg
        host, port = parse_host_port(cfg.asterix_udp, "asterix_udp")
        self.decoder = AsterixStreamDecoder(
            date=cfg.date,
            sites=asterix_sites(cfg),
            sector_count=cfg.sector_count,
            max_plot_delay=0.0 if cfg.max_plot_delay is None else cfg.max_plot_delay,
            report_window=cfg.report_window,
            adsb_sigma=cfg.adsb_sigma,
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
        self._clock_warned = False
        self.fleet = RadarFleet(session, f"sensor-{cfg.radar or 'asterix-udp'}", cfg.cache_batches)
        self.sequence = SequenceCeiling(
            cfg.state_dir or state_home() / f"sensor-{cfg.radar or 'asterix-udp'}"
        )

    def _publish(self, batches: list[PlotBatch], stamp_ns: int) -> None:
        for b in batches:
            if self.cfg.radar is not None and b.radar_id != self.cfg.radar:
                self.filtered += 1
                continue
            seq = self.sequence.number(b.radar_id, b.seq)  # continues across restarts
            ident = {"seq": seq, "epoch": self.sequence.epoch}
            self.fleet.plots(b.model_copy(update=ident), stamp_ns)

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
        if self.cfg.date is None:
            log.info(
                "no --date: each record's UTC day is the one nearest to the receive clock "
                "(give --date YYYY-MM-DD when playing an old capture)"
            )
        wall0 = time.monotonic()
        next_sites = next_status = wall0
        while not stop.is_set():
            if duration is not None and time.monotonic() - wall0 >= duration:
                break
            try:
                data = self.sock.recv(65_535)
            except TimeoutError:
                data = None
            if data:
                self._receive(data)
            now = time.monotonic()
            if now >= next_sites:
                next_sites = now + self.SITE_CHECK_S
                self._sites()
            if now >= next_status:
                next_status = now + self.cfg.status_interval
                self._status(wall0)
        self._drain()
        self._sites()
        self._publish(self.decoder.flush(), time.time_ns())
        self._status(wall0)
        return self.fleet.stats

    DRAIN_MAX = 10_000
    """Datagrams read at most at a stop from what the socket already holds."""

    def _drain(self) -> None:
        """At a stop, decode and publish the datagrams the kernel has already received
        (at most :attr:`DRAIN_MAX`, without waiting for more), so the sectors flushed
        next are complete: a stop never drops data that had arrived."""
        self.sock.setblocking(False)
        for _ in range(self.DRAIN_MAX):
            try:
                data = self.sock.recv(65_535)
            except OSError:  # BlockingIOError: nothing more received
                break
            self._receive(data)

    def _receive(self, data: bytes) -> None:
        """Decode one datagram and publish the sectors it completes."""
        now_ns = time.time_ns()
        self.datagrams += 1
        batches = self.decoder.feed(data, now_ns)
        self._check_clock(batches, now_ns)
        new = {b.radar_id for b in batches} - set(self.fleet.sites)
        if new and time.monotonic() - self._new_site_check > 0.2:
            self._new_site_check = time.monotonic()
            self._sites()  # a new radar's site goes out before its first batch
        self._publish(batches, now_ns)

    def _check_clock(self, batches: list[PlotBatch], now_ns: int) -> None:
        """Warn once when record times are more than STALE_S from the receive clock."""
        if self._clock_warned or not batches:
            return
        off_s = (max(b.time_end for b in batches) - now_ns) / 1e9
        if abs(off_s) > STALE_S:
            self._clock_warned = True
            log.warning(
                "ASTERIX record times are %.1f h %s the receive clock (date %s): an old "
                "capture? give --date YYYY-MM-DD, the UTC date of its first record",
                abs(off_s) / 3600,
                "ahead of" if off_s > 0 else "behind",
                self.cfg.date or "from the receive clock",
            )

    def _status(self, wall0: float) -> None:
        st = self.decoder.stats
        self.fleet.status(
            wall0,
            {"datagrams": self.datagrams, **{k: v for k, v in st.items() if isinstance(v, int)}},
            stats_text(dict(st)),
        )

    def close(self) -> None:
        self.sock.close()
        self.fleet.close()
