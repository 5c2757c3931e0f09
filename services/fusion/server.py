"""The fusion service's network side: the Zenoh subscriptions, the active/standby
election, the service loop, the publishers and queryables of the track feed, Status and
snapshot, and the bounded shutdown drain. The computation is :class:`FusionCore`
(:mod:`.service`); ``skyfuse fusion`` (``services/cli/cmd_fusion.py``) parses the
configuration and calls :func:`serve`."""

from __future__ import annotations

import logging
import time

from skyfuse.schemas import keys
from skyfuse.services.fusion.kernel_cache import timed_load
from skyfuse.services.fusion.service import FusionCore
from skyfuse.services.fusion.standby import (
    Election,
    Follower,
    FusionIdTaken,
    StateFollower,
    become_active,
    standby_status,
)
from skyfuse.services.runtime.lifecycle import EXIT_FAILED, EXIT_OK
from skyfuse.services.runtime.startup_heap import freeze_startup_heap
from skyfuse.services.runtime.transport import (
    Inbox,
    declare_liveliness,
    declare_publisher,
    payload_encoding,
    query,
    service_alive_key,
)

log = logging.getLogger("skyfuse.fusion")


def make_pipeline_factory(
    tracker_cfg, fusion_id: str, *, assumed_altitude: float | None = None, registration=None
):
    """``frame -> pipeline``: the conversion + tracker + TrackBatch code path shared with
    ``skyfuse track`` (``registration``: a RegistrationConfig, default on)."""
    from skyfuse.services.fusion.pipeline import TrackPipeline

    def factory(frame):
        return TrackPipeline(
            frame,
            tracker_cfg,
            fusion_id=fusion_id,
            assumed_altitude=assumed_altitude,
            registration=registration,
        )

    return factory


def serve(
    session, core: FusionCore, stop, *, duration: float | None = None, cat062=None, persist=None
) -> int:
    """The service loop: until ``stop`` is set (or ``duration`` s elapse). ``cat062``: an
    object with ``send(TrackBatch)`` and ``terminated(TrackEvent)`` that also gets every
    output (``skyfuse fusion --cat062-udp``: the CAT062 UDP sender); ``persist``: a
    :class:`~skyfuse.services.fusion.state_store.Persistence` (resume, snapshots). Publishes
    only as the active instance of its fusion id (:mod:`.standby`); returns the exit status
    (1: another instance holds the id)."""
    # the compiled kernels load now, not on the first batches (their latency); compiled
    # first if the cache is cold (skyfuse warmup), with a line that says so
    timed_load(log)
    inbox = Inbox(capacity=core.cfg.inbox)
    inbox.subscribe(session, keys.ALL_SITES, "site")
    inbox.subscribe(session, keys.ALL_PLOTS, "plots", recover=True)  # from the sensors' caches
    inbox.subscribe_liveliness(session, keys.ALL_ALIVE, "alive")
    election = Election(session, core.cfg.fusion_id)
    keep = 2 * (core.cfg.snapshot_interval or 0.0) + core.cfg.max_lateness + 5.0
    follower = Follower(core.cfg.inbox, keep)
    standby = _Standby(session, core, election, follower, persist)
    try:
        if not become_active(
            election, inbox, stop, standby=core.cfg.standby, follower=follower, tick=standby.tick
        ):
            inbox.close()
            return EXIT_OK
    except FusionIdTaken:
        inbox.close()
        election.close()
        raise
    finally:
        standby.close()
    core.role = "active"
    if persist is not None:
        persist.start(standby.state())
        core.buffer.seen.max_jump = core.cfg.max_seq_jump  # the configured one, not the saved
    svc = _Service(session, core, cat062, persist)
    for item in follower.newer_than_state(core):  # received while in standby
        svc.handle(item)
    # sites published before we joined: ask the sensors' queryables
    for key, payload in query(session, keys.ALL_SITES, timeout=1.0):
        core.on_site_payload(key, payload)
    freeze_startup_heap()  # again after the kernels and the resumed state: before traffic
    token = declare_liveliness(session, service_alive_key("fusion"))
    log.info("fusion %s running (reorder wait %.2f s)", core.cfg.fusion_id, core.cfg.reorder_wait)
    try:
        return _loop(svc, inbox, stop, duration, election, persist)
    finally:
        token.undeclare()
        inbox.close()
        if persist is not None:  # the state at the stop, whatever the drain below costs
            persist.save()
        if svc.shutdown(inbox, getattr(stop, "grace", 4.5)) and persist is not None:
            persist.save()  # and with what the drain applied, when it finished in time
        election.close()


def _loop(svc: _Service, inbox: Inbox, stop, duration, election, persist) -> int:
    core = svc.core
    t0 = time.monotonic()
    next_status = t0
    while not stop.is_set():
        now = time.monotonic()
        if duration is not None and now - t0 >= duration:
            break
        if not election.is_active():  # a smaller token appeared: never two publishers
            log.error("fusion %s: instance %s is active too: stopping", core.cfg.fusion_id,
                      election.leader())  # fmt: skip
            return EXIT_FAILED
        room = core.cfg.queue - len(core.buffer)
        if room > 0 and not core.over_backlog(now):
            item = inbox.get(timeout=_next_wait(core, now))
            if item is not None:
                svc.handle(item)
                for more in inbox.drain(min(1000, room)):
                    svc.handle(more)
        else:  # stop reading: the bounded inbox fills, Zenoh (BLOCK) slows the senders
            core.counters["reading_paused"] += 1
            time.sleep(min(0.01, _next_wait(core, now)))
        for out in core.ready_cycles(budget_s=0.2):  # each group published when done
            svc.publish([out])
        if persist is not None:
            persist.tick(time.monotonic())
        if time.monotonic() >= next_status:
            next_status = time.monotonic() + core.cfg.status_interval
            svc.publish_status(inbox)
    return EXIT_OK


class _Standby:
    """While this instance is a standby: the active one's snapshots over Zenoh and this
    instance's own Status (``services.fusion.standby``)."""

    def __init__(self, session, core: FusionCore, election, follower, persist) -> None:
        self.core, self.election, self.follower = core, election, follower
        self.states = self.pub = None
        self._next_status = 0.0
        if not core.cfg.standby:
            return
        fid = core.cfg.fusion_id
        if persist is not None:
            self.states = StateFollower(session, fid, persist.store, core.cfg.state_max_bytes)
        self.pub = declare_publisher(session, keys.fusion_standby_status(fid, election.name))

    def tick(self) -> None:
        if self.states is not None:
            self.states.poll()
        if self.pub is not None and time.monotonic() >= self._next_status:
            self._next_status = time.monotonic() + self.core.cfg.status_interval
            st = standby_status(self.core, self.election, self.follower, self.states)
            self.pub.put(st.to_json_bytes())

    def state(self) -> dict | None:
        """The newest valid snapshot received (``None``: none, or not a standby)."""
        return None if self.states is None else self.states.state

    def close(self) -> None:
        if self.states is not None:
            self.states.close()
        if self.pub is not None:
            self.pub.undeclare()


class _Service:
    """The fusion service's Zenoh side: publishers, queryables (snapshot, Status), input
    handling and the shutdown drain."""

    def __init__(self, session, core: FusionCore, cat062, persist=None) -> None:
        fid = core.cfg.fusion_id
        self.session, self.core, self.cat062, self.persist = session, core, cat062, persist
        self.pub_tracks = declare_publisher(session, keys.fusion_tracks(fid))
        self.pub_events = declare_publisher(session, keys.fusion_events(fid))
        self.pub_status = declare_publisher(session, keys.fusion_status(fid))
        self.pub_registration = declare_publisher(session, keys.fusion_registration(fid))
        self.snapshot_key, self.status_key = keys.fusion_snapshot(fid), keys.fusion_status(fid)
        if persist is not None:  # snapshots for standbys on other hosts
            persist.publish = declare_publisher(session, keys.fusion_state(fid)).put
        self.last_status = core.status().to_json_bytes()
        self.queryables = [
            session.declare_queryable(self.snapshot_key, self._answer_snapshot),
            session.declare_queryable(self.status_key, self._answer_status),
        ]
        self.asked_site: dict[str, float] = {}

    def _answer_snapshot(self, q) -> None:
        payload = self.core.snapshot_payload()
        if payload is not None:
            q.reply(self.snapshot_key, payload, encoding=payload_encoding(self.snapshot_key))
        else:
            q.reply_err(b"no tracks yet")

    def _answer_status(self, q) -> None:  # the last Status published (status_interval old)
        q.reply(self.status_key, self.last_status, encoding=payload_encoding(self.status_key))

    def publish_status(self, inbox: Inbox | None = None) -> None:
        """The Status, and its registration part on its own key (once the pipeline runs);
        first the samples ``inbox`` reported missed since the last one."""
        if inbox is not None:
            self.core.note_missed(inbox.take_missed())
        st = self.core.status()
        self.last_status = st.to_json_bytes()
        self.pub_status.put(self.last_status)
        if st.registration is not None:
            self.pub_registration.put(st.registration.to_json_bytes())

    def publish(self, outputs) -> None:
        if outputs and self.persist is not None:
            self.persist.guard_ids()  # every id published is below the persisted ceiling
        for out in outputs:
            for msg in (out.tracks, out.full):
                if msg is None:
                    continue
                self.pub_tracks.put(msg.to_json_bytes())
                if self.cat062 is not None:
                    self.cat062.send(msg.model())
            for ev in out.events:
                self.pub_events.put(ev.to_json_bytes())
                if self.cat062 is not None:
                    self.cat062.terminated(ev)
            self.core.published(out)

    def handle(self, item) -> None:
        core = self.core
        if item.tag == "plots":
            batch = core.on_plots_payload(
                item.key, item.payload, _arrival(item.recv_ns), item.sent_ns, recv_ns=item.recv_ns
            )
            if batch is not None:
                r = core.radars.get(batch.radar_id)
                if r is not None and r.site is None:
                    self._ask_site(batch.radar_id)
        elif item.tag == "site":
            core.on_site_payload(item.key, item.payload)
        elif item.tag == "alive":
            core.on_alive(item.key, item.put)

    def _ask_site(self, radar_id: str) -> None:
        """Ask the sensor's site queryable, at most once a second per radar."""
        now = time.monotonic()
        if now - self.asked_site.get(radar_id, -1e9) > 1.0:
            self.asked_site[radar_id] = now
            for key, payload in query(self.session, keys.radar_site(radar_id), 0.5):
                self.core.on_site_payload(key, payload)

    def shutdown(self, inbox: Inbox, grace: float) -> bool:
        """Apply what was already received, but never past the shutdown deadline; then
        the last Status and a summary line. Whether it applied anything within the
        deadline (the caller saves the state again)."""
        core, late = self.core, "not processed: shutdown deadline"
        cycles = core.counters["cycles"]
        deadline = time.monotonic() + max(0.5, grace - 1.5)
        left = inbox.drain(1_000_000)
        for i, item in enumerate(left):
            if time.monotonic() > deadline:
                core.rejected[late] += len(left) - i
                break
            self.handle(item)
        pending = core.buffer.flush()
        while pending and time.monotonic() <= deadline:
            group, pending = pending[: core.cfg.bulk_max], pending[core.cfg.bulk_max :]
            self.publish(list(core.cycle_group(group)))
        if pending:
            core.rejected[late] += len(pending)
        if inbox.discarded:
            core.rejected["not processed: arrived after the stop"] += inbox.discarded
        if core.rejected.get(late):
            log.error("shutdown deadline: %d batches not processed", core.rejected[late])
        self.publish_status(inbox)
        for q in self.queryables:
            q.undeclare()
        applied = core.counters["cycles"] > cycles and time.monotonic() <= deadline
        st, c = core.status(), core.counters
        log.info(
            "fusion %s: %d batches (%d plots) in, %d cycles, %s confirmed tracks; latency "
            "p50 %s ms p99 %s ms; rejected %s",
            core.cfg.fusion_id, c["batches_in"], c["plots_in"], c["cycles"],
            st.tracks_confirmed, _fmt(st.latency_ms.p50), _fmt(st.latency_ms.p99),
            dict(core.rejected) or "none",
        )  # fmt: skip
        return applied


def _arrival(recv_ns: int) -> float:
    """The monotonic time a sample was received (by Zenoh's delivery thread, before it
    waited in the inbox): the reorder hold counts from there, not from when the main
    loop read it. A wall-clock step while it waited moves it at most 60 s."""
    waited = min(max(0.0, (time.time_ns() - recv_ns) * 1e-9), 60.0)
    return time.monotonic() - waited


def _next_wait(core: FusionCore, now: float) -> float:
    """Sleep until the head of the reorder buffer is due (at most 50 ms)."""
    due = core.buffer.next_due()
    if due is None:
        return 0.05
    return min(0.05, max(0.0, due - now))


def _fmt(v) -> str:
    return "-" if v is None else f"{v:.1f}"
