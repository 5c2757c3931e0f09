"""A sensor process publishing every sensor of an ASTERIX recording (pcap of UDP or raw
``.ast``: CAT048/CAT034 radars, CAT010/CAT020/CAT021 surface movement radar,
multilateration, ADS-B), paced by the plot times (``skyfuse sensor --asterix FILE``)."""

from __future__ import annotations

import logging
import time

from skyfuse.services.runtime.config import ConfigError
from skyfuse.services.sensors.config import SensorServiceConfig, SensorStats, start_time_ns
from skyfuse.services.sensors.continuation import file_epoch
from skyfuse.services.sensors.fleet import RadarFleet, asterix_sites, stats_text

log = logging.getLogger(__name__)


class AsterixRecordingSensor:
    """Publishes every radar of an ASTERIX recording (``cfg.asterix``) on Zenoh.

    The file is decoded with :func:`services.asterix.read_asterix` (sites from
    ``cfg.sites``, else CAT034 I120); then the sites are published (message, queryable,
    liveliness token per radar) and the sector batches of all radars in ``time_end``
    order, paced as ``wall(t) = wall0 + (t − t0) / speed`` with ``t0`` the first batch's
    end (``cfg.data_start`` instead: processes publishing recordings of one period in step).
    Each batch's attachment is ``wall(time_end)``. ``cfg.radar`` restricts the
    publication to one radar. Radars without a known position still publish batches and
    liveliness (the fusion service counts them as "no site for radar") and are named in
    the log, with the sites-file entry they need."""

    def __init__(self, session, cfg: SensorServiceConfig) -> None:
        from skyfuse.services.asterix import read_asterix

        if not cfg.asterix.is_file():
            raise ConfigError(f"asterix {str(cfg.asterix)!r} does not exist")
        self.cfg = cfg
        delay = 30.0 if cfg.max_plot_delay is None else cfg.max_plot_delay
        self.result = read_asterix(
            cfg.asterix,
            date=cfg.date,
            sites=asterix_sites(cfg),
            sector_count=cfg.sector_count,
            max_plot_delay=delay,
            report_window=cfg.report_window,
            adsb_sigma=cfg.adsb_sigma,
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
        # the same file decoded the same way: the same epoch, so a restarted sensor's
        # repeats are duplicates by (radar, epoch, seq) (services.sensors.continuation)
        self.epoch = file_epoch(
            cfg.asterix,
            cfg.date,
            cfg.sector_count,
            delay,
            cfg.sites,
            cfg.report_window,
            cfg.adsb_sigma,
        )
        self.batches = [
            b.model_copy(update={"epoch": self.epoch})
            for b in self.result.batches
            if b.radar_id in radars
        ]
        self.fleet = RadarFleet(session, f"sensor-{cfg.radar or 'asterix'}", cfg.cache_batches)

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
            stats_text(res.stats),
        )
        start_ns = start_time_ns(cfg)
        wall0 = time.monotonic()
        next_status = wall0
        t0 = self.batches[0].time_end if self.batches else 0
        if cfg.data_start is not None:
            t0 = round(cfg.data_start * 1e9)
        for batch in self.batches:
            due_ns = start_ns + int((batch.time_end - t0) / cfg.speed)
            if not fleet.stats.wait_until(due_ns, stop):
                break
            fleet.plots(batch, due_ns)
            now = time.monotonic()
            if now >= next_status:
                next_status = now + cfg.status_interval
                fleet.status(wall0, {}, f"late by up to {fleet.stats.late_s:.3f} s")
        fleet.status(wall0, {}, f"late by up to {fleet.stats.late_s:.3f} s")
        return fleet.stats

    def close(self) -> None:
        self.fleet.close()
