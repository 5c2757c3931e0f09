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

import logging
import time

from skyfuse.schemas import RadarSite, Status, keys
from skyfuse.services.runtime.config import ConfigError
from skyfuse.services.runtime.transport import (
    declare_cached_publisher,
    declare_liveliness,
    declare_publisher,
    service_alive_key,
    wall_stamp,
)
from skyfuse.services.sensors.config import SensorServiceConfig, SensorStats, start_time_ns
from skyfuse.services.sensors.continuation import SensorProgress, new_epoch

log = logging.getLogger(__name__)


def load_scenario(cfg: SensorServiceConfig):
    """The scenario of ``cfg`` and this radar's site (``ConfigError`` if absent)."""
    sc = cfg.build_scenario()
    ids = [s.radar_id for s in sc.sites]
    if cfg.radar not in ids:
        raise ConfigError(
            f"radar {cfg.radar!r} is not in scenario {cfg.scenario!r}: its radars are "
            + ", ".join(ids)
        )
    return sc, sc.sites[ids.index(cfg.radar)]


class SimulatedRadar:
    """Publishes one radar's site and plots from the scenario simulator."""

    def __init__(self, session, cfg: SensorServiceConfig) -> None:
        self.session = session
        self.cfg = cfg
        self.scenario, self.site = load_scenario(cfg)
        self.stats = SensorStats()
        self._site_bytes = self.site.to_json_bytes()
        self._pub_site = declare_publisher(session, keys.radar_site(cfg.radar))
        self._pub_plots = declare_cached_publisher(
            session, keys.radar_plots(cfg.radar), cfg.cache_batches
        )
        self._pub_truth = declare_publisher(session, keys.SIM_TRUTH) if cfg.truth else None
        self._pub_status = declare_publisher(session, keys.service_status(f"sensor-{cfg.radar}"))
        self._queryable = session.declare_queryable(keys.radar_site(cfg.radar), self._answer_site)
        self._token = None
        self._ready = declare_liveliness(session, service_alive_key(f"sensor-{cfg.radar}"))
        self.progress = SensorProgress.from_config(cfg)
        self.epoch = new_epoch()
        """``PlotBatch.epoch``: the progress file's when continued (see ``run``)."""

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
        skip = None if self.progress is None else self.progress.resume_after()
        if self.progress is not None:
            self.epoch = self.progress.epoch
        if skip is not None:
            t0 = None  # the first batch not yet published is due at the start instant
        next_status = wall0
        for ev in Simulator(self.scenario, seed=cfg.seed).run():
            if not self._mine(ev):
                continue
            if skip is not None and ev.time <= skip:
                # published by the previous run (services.sensors.continuation); a site
                # of that part is the current site, published now and not paced: it
                # must not set the pacing origin, which is the first batch not published
                if ev.kind == "site" and ev.message.to_json_bytes() != self._site_bytes:
                    self.publish_site(ev.message)
                continue
            if t0 is None:
                t0 = ev.time
            due_ns = start_ns + int((ev.time - t0) / cfg.speed)
            if not self.stats.wait_until(due_ns, stop):
                break
            self._publish(ev, due_ns)
            now = time.monotonic()
            if now >= next_status:
                next_status = now + cfg.status_interval
                self._status(wall0)
        self._status(wall0)
        if self.progress is not None:
            if self.stats.interrupted:
                self.progress.write()  # a restart continues after the last batch
            else:
                self.progress.finished()  # the scenario is done: a new run starts afresh
        return self.stats

    def _mine(self, ev) -> bool:
        """Whether this sensor publishes the simulator event ``ev``: its radar's, and the
        truth when asked for."""
        if ev.kind == "truth":
            return self._pub_truth is not None
        return getattr(ev.message, "radar_id", None) == self.cfg.radar

    def _publish(self, ev, due_ns: int) -> None:
        """Publish one event of this radar (or the truth) due at wall clock ``due_ns``."""
        if ev.kind == "plots":
            ev.message.epoch = self.epoch
            self._pub_plots.put(ev.message.to_json_bytes(), attachment=wall_stamp(due_ns))
            self.stats.plots += len(ev.message.time)
            self.stats.published["plots"] += 1
            if self.progress is not None:
                self.progress.published(ev.message.seq, ev.message.time_end)
        elif ev.kind == "site":
            if ev.message.to_json_bytes() != self._site_bytes:
                self.publish_site(ev.message)
        else:
            self._pub_truth.put(ev.message.to_json_bytes())
            self.stats.published["truth"] += 1

    def close(self) -> None:
        if self._ready is not None:
            self._ready.undeclare()
            self._ready = None
        if self._token is not None:
            self._token.undeclare()
            self._token = None
        self._queryable.undeclare()
