"""The Zenoh side of a sensor process that serves several radars (ASTERIX input: a
recording or a live UDP feed), and what the two ASTERIX sources share (the sites file,
the decoder counts in words)."""

from __future__ import annotations

import time
from collections import Counter

from skyfuse.schemas import PlotBatch, RadarSite, Status, keys
from skyfuse.services.runtime.config import ConfigError
from skyfuse.services.runtime.transport import (
    PLOT_CACHE,
    declare_cached_publisher,
    declare_liveliness,
    declare_publisher,
    service_alive_key,
    wall_stamp,
)
from skyfuse.services.sensors.config import SensorServiceConfig, SensorStats


class RadarFleet:
    """Zenoh side of a sensor process that serves several radars (ASTERIX input).

    Per radar: a ``RadarSite`` message and a queryable on ``radar/{id}/site`` once its
    site is known, a liveliness token ``radar/{id}/alive`` from its first site or batch
    on, and its ``PlotBatch`` publications (BLOCK publishers). ``service`` names the
    process's own ready token and status key; ``cache``: plot batches each radar's
    publisher keeps for receivers that missed them."""

    def __init__(self, session, service: str, cache: int = PLOT_CACHE) -> None:
        self.session = session
        self.service = service
        self.cache = cache
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
            pub = self._pub_plots[rid] = declare_cached_publisher(
                self.session, keys.radar_plots(rid), self.cache
            )
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


def asterix_sites(cfg: SensorServiceConfig) -> dict[str, RadarSite] | None:
    if cfg.sites is None:
        return None
    from skyfuse.services.asterix import SitesError, load_sites

    try:
        return load_sites(cfg.sites)
    except (SitesError, OSError) as e:
        raise ConfigError(str(e)) from None


def stats_text(stats: dict[str, int]) -> str:
    keep = ("plots", "batches", "duplicate_records", "late_plots", "radars_without_site")
    bad = {k: v for k, v in stats.items() if "malformed" in k or k.startswith("unknown_category")}
    return ", ".join(f"{k} {stats[k]}" for k in keep if stats.get(k)) + (
        f"; problems {bad}" if bad else ""
    )
