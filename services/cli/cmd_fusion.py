"""``skyfuse fusion [--config fusion.toml] [--listen EP] [--connect EP]``: the fusion
service. Subscribes to every radar's plots and sites, orders batches across radars,
runs the configured tracker and publishes on ``skyfuse/@v1/fusion/{id}/…``:
``tracks`` (a TrackBatch after each cycle), ``events`` (TrackEvents), ``status``
(periodic Status), ``registration`` (the radar bias estimates, RegistrationStatus, with
each Status) and the queryable ``snapshot`` (the latest TrackBatch).

TOML: ``[fusion]`` (this service, incl. ``[[fusion.sites]]``), ``[tracker]`` (the
tracker, see ``fusion.tracker.TrackerConfig``), ``[registration]`` (the online sensor
registration, ``fusion.registration.RegistrationConfig``), ``[transport]``. Environment:
``SKYFUSE_FUSION_*``, ``SKYFUSE_TRACKER_*``, ``SKYFUSE_REGISTRATION_*``, ``SKYFUSE_*``
(transport).

Exits 0 on SIGINT/SIGTERM (after applying what is buffered), 1 if the network fails,
2 on a bad configuration."""

from __future__ import annotations

import argparse
import logging
import time

from skyfuse.schemas import keys
from skyfuse.services.cli.config import (
    ConfigError,
    add_model_arguments,
    build_config,
)
from skyfuse.services.cli.service_command import add_service_parser, run_service, service_config
from skyfuse.services.fusion.registration_link import (
    add_registration_arguments,
    registration_config,
)
from skyfuse.services.fusion.service import FusionConfig, FusionCore
from skyfuse.services.runtime.transport import (
    Inbox,
    add_transport_arguments,
    declare_liveliness,
    declare_publisher,
    query,
    service_alive_key,
)

log = logging.getLogger("skyfuse.fusion")


def _tracker_config_model():
    from skyfuse.fusion.tracker import TrackerConfig

    return TrackerConfig


def register(sub: argparse._SubParsersAction) -> None:
    p = add_service_parser(
        sub, "fusion", "run the fusion service (plots in, fused tracks out)", __doc__,
        FusionConfig, tables="[fusion], [tracker] and [transport]", transport=False,
        skip=("sites",),
    )  # fmt: skip
    group = p.add_argument_group(
        "tracker",
        "The tracker (the same flags as skyfuse track and eval); also the [tracker] TOML "
        "table and SKYFUSE_TRACKER_<FIELD>",
    )
    add_model_arguments(group, _tracker_config_model())
    add_registration_arguments(p)
    cat = p.add_argument_group("ASTERIX CAT062 output (see skyfuse cat062)")
    cat.add_argument(
        "--cat062-udp",
        default=None,
        metavar="HOST:PORT",
        help="Also send every TrackBatch as CAT062 UDP datagrams to HOST:PORT",
    )
    cat.add_argument("--cat062-sac", type=int, default=0, help="I062/010 SAC (default: 0)")
    cat.add_argument("--cat062-sic", type=int, default=1, help="I062/010 SIC (default: 1)")
    add_transport_arguments(p)  # last: after the CAT062 group, as in the other commands
    p.set_defaults(func=run)


def tracker_config(args: argparse.Namespace):
    """The TrackerConfig: defaults < TOML [tracker] < SKYFUSE_TRACKER_* < flags."""
    return build_config(
        _tracker_config_model(),
        args,
        toml_path=getattr(args, "config", None),
        section="tracker",
        env_prefix="SKYFUSE_TRACKER_",
    )


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


def run(args: argparse.Namespace) -> int:
    cfg, tcfg = service_config(FusionConfig, args, "fusion")
    tracker_cfg = tracker_config(args)
    reg_cfg = registration_config(args, toml_path=getattr(args, "config", None))
    core = FusionCore(
        cfg,
        make_pipeline_factory(
            tracker_cfg, cfg.fusion_id, assumed_altitude=cfg.assumed_altitude, registration=reg_cfg
        ),
    )
    cat062 = None
    if getattr(args, "cat062_udp", None):
        from skyfuse.services.cli.cmd_cat062 import Cat062UdpSender

        try:
            cat062 = Cat062UdpSender(args.cat062_udp, sac=args.cat062_sac, sic=args.cat062_sic)
        except ValueError as e:
            raise ConfigError(str(e)) from None
    try:
        return run_service(tcfg, lambda session, stop: serve(session, core, stop, cat062=cat062))
    finally:
        if cat062 is not None:
            log.info("cat062 output: %s", dict(cat062.stats))
            cat062.close()


def serve(session, core: FusionCore, stop, *, duration: float | None = None, cat062=None) -> None:
    """The service loop: until ``stop`` is set (or ``duration`` s elapse). ``cat062``: a
    :class:`services.cmd_cat062.Cat062UdpSender` that also gets every output."""
    fid = core.cfg.fusion_id
    pub_tracks = declare_publisher(session, keys.fusion_tracks(fid))
    pub_events = declare_publisher(session, keys.fusion_events(fid))
    pub_status = declare_publisher(session, keys.fusion_status(fid))
    pub_registration = declare_publisher(session, keys.fusion_registration(fid))
    snapshot_key = keys.fusion_snapshot(fid)
    latest = {"payload": None}

    def answer_snapshot(q) -> None:
        payload = latest["payload"]
        if payload is not None:
            q.reply(snapshot_key, payload)
        else:
            q.reply_err(b"no tracks yet")

    queryable = session.declare_queryable(snapshot_key, answer_snapshot)
    inbox = _open_inputs(session, core)
    token = declare_liveliness(session, service_alive_key("fusion"))
    log.info("fusion %s running (reorder wait %.2f s)", fid, core.cfg.reorder_wait)
    t0 = time.monotonic()
    next_status = t0
    asked_site: dict[str, float] = {}

    def publish(outputs) -> None:
        for out in outputs:
            b = out.tracks
            payload = b.to_json_bytes()
            pub_tracks.put(payload)
            if cat062 is not None:
                cat062.send(b)
            for ev in out.events:
                pub_events.put(ev.to_json_bytes())
                if cat062 is not None:
                    cat062.terminated(ev)
            latest["payload"] = payload
            core.published(out)

    def handle(item) -> None:
        if item.tag == "plots":
            batch = core.on_plots_payload(item.key, item.payload, time.monotonic(), item.sent_ns)
            if batch is not None:
                r = core.radars.get(batch.radar_id)
                if r is not None and r.site is None:
                    # ask the sensor's queryable, at most once a second per radar
                    now = time.monotonic()
                    if now - asked_site.get(batch.radar_id, -1e9) > 1.0:
                        asked_site[batch.radar_id] = now
                        for key, payload in query(session, keys.radar_site(batch.radar_id), 0.5):
                            core.on_site_payload(key, payload)
        elif item.tag == "site":
            core.on_site_payload(item.key, item.payload)
        elif item.tag == "alive":
            core.on_alive(item.key, item.put)

    try:
        while not stop.is_set():
            now = time.monotonic()
            if duration is not None and now - t0 >= duration:
                break
            room = core.cfg.queue - len(core.buffer)
            if room > 0:  # a full reorder buffer stops the reading: back-pressure (BLOCK)
                item = inbox.get(timeout=_next_wait(core, now))
                if item is not None:
                    handle(item)
                    for more in inbox.drain(min(1000, room)):
                        handle(more)
            publish(core.poll(budget_s=0.2))
            if time.monotonic() >= next_status:
                next_status = time.monotonic() + core.cfg.status_interval
                _publish_status(core.status(), pub_status, pub_registration)
    finally:
        token.undeclare()
        inbox.close()
        _drain_on_stop(core, inbox, handle, publish, stop)
        st = core.status()
        _publish_status(st, pub_status, pub_registration)
        queryable.undeclare()
        _log_totals(core, st)


def _publish_status(st, pub_status, pub_registration) -> None:
    """The Status, and its registration part on its own key (once the pipeline runs)."""
    pub_status.put(st.to_json_bytes())
    if st.registration is not None:
        pub_registration.put(st.registration.to_json_bytes())


def _open_inputs(session, core: FusionCore) -> Inbox:
    """Subscribe to the sites, plots and radar liveliness; take the sites published
    before we joined from the sensors' queryables."""
    inbox = Inbox(capacity=core.cfg.queue)
    inbox.subscribe(session, keys.ALL_SITES, "site")
    inbox.subscribe(session, keys.ALL_PLOTS, "plots")
    inbox.subscribe_liveliness(session, keys.ALL_ALIVE, "alive")
    for key, payload in query(session, keys.ALL_SITES, timeout=1.0):
        core.on_site_payload(key, payload)
    return inbox


def _drain_on_stop(core: FusionCore, inbox, handle, publish, stop) -> None:
    """Apply what was already received, but never past the shutdown deadline."""
    grace = getattr(stop, "grace", 4.5)
    deadline = time.monotonic() + max(0.5, grace - 1.5)
    left = inbox.drain(1_000_000)
    for i, item in enumerate(left):
        if time.monotonic() > deadline:
            core.rejected["not processed: shutdown deadline"] += len(left) - i
            break
        handle(item)
    for p in core.buffer.flush():
        if time.monotonic() > deadline:
            core.rejected["not processed: shutdown deadline"] += 1
            continue
        publish([o for o in [core.cycle(p)] if o is not None])
    if inbox.discarded:
        core.rejected["not processed: arrived after the stop"] += inbox.discarded
    if core.rejected.get("not processed: shutdown deadline"):
        log.error(
            "shutdown deadline: %d batches not processed",
            core.rejected["not processed: shutdown deadline"],
        )


def _log_totals(core: FusionCore, st) -> None:
    lat = st.latency_ms
    log.info(
        "fusion %s: %d batches (%d plots) in, %d cycles, %s confirmed tracks; latency "
        "p50 %s ms p99 %s ms; rejected %s",
        core.cfg.fusion_id,
        core.counters["batches_in"],
        core.counters["plots_in"],
        core.counters["cycles"],
        st.tracks_confirmed,
        _fmt(lat.p50),
        _fmt(lat.p99),
        dict(core.rejected) or "none",
    )


def _next_wait(core: FusionCore, now: float) -> float:
    """Sleep until the head of the reorder buffer is due (at most 50 ms)."""
    due = core.buffer.next_due()
    if due is None:
        return 0.05
    return min(0.05, max(0.0, due - now))


def _fmt(v) -> str:
    return "-" if v is None else f"{v:.1f}"
