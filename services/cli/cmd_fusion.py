"""``skyfuse fusion [--config fusion.toml] [--listen EP] [--connect EP]``: the fusion
service. Subscribes to every radar's plots and sites, orders batches across radars,
runs the configured tracker and publishes on ``skyfuse/@v1/fusion/{id}/…``:
``tracks`` (a TrackBatch after each cycle), ``events`` (TrackEvents), ``status``
(periodic Status) and the queryable ``snapshot`` (the latest TrackBatch).

TOML: ``[fusion]`` (this service, incl. ``[[fusion.sites]]``), ``[tracker]`` (the
tracker, see ``fusion.tracker.TrackerConfig``), ``[transport]``. Environment:
``SKYFUSE_FUSION_*``, ``SKYFUSE_TRACKER_*``, ``SKYFUSE_*`` (transport).

Exits 0 on SIGINT/SIGTERM (after applying what is buffered), 1 if the network fails,
2 on a bad configuration."""

from __future__ import annotations

import argparse
import logging
import time

from skyfuse.fusion.tracker.registry import tracker_help
from skyfuse.schemas import keys
from skyfuse.services.cli.config import (
    ConfigError,
    _split_list,
    add_model_arguments,
    build_config,
    parse_key_values,
)
from skyfuse.services.fusion.service import FusionConfig, FusionCore
from skyfuse.services.runtime.lifecycle import EXIT_FAILED, EXIT_OK, StopFlag
from skyfuse.services.runtime.transport import (
    Inbox,
    TransportError,
    add_transport_arguments,
    declare_liveliness,
    declare_publisher,
    open_session,
    query,
    service_alive_key,
    transport_config,
)

log = logging.getLogger("skyfuse.fusion")


def _tracker_config_model():
    from skyfuse.fusion.tracker import TrackerConfig

    return TrackerConfig


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "fusion",
        help="run the fusion service (plots in, fused tracks out)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--config", default=None, help="TOML file: [fusion], [tracker], [transport]")
    add_model_arguments(p, FusionConfig, skip=("sites",))
    group = p.add_argument_group(
        "tracker",
        "Every field of fusion.tracker.TrackerConfig can be set in the [tracker] "
        "TOML table, as SKYFUSE_TRACKER_<FIELD>, or with --tracker-set FIELD=VALUE,...",
    )
    group.add_argument(
        "--tracker",
        default=argparse.SUPPRESS,
        help="Tracker: " + tracker_help() + " (default: lmits)",
    )
    group.add_argument(
        "--tracker-set",
        type=_split_list,
        default=argparse.SUPPRESS,
        metavar="FIELD=VALUE,...",
        help="Tracker settings, e.g. depth=2,p_gate=0.995",
    )
    cat = p.add_argument_group("ASTERIX CAT062 output (see skyfuse cat062)")
    cat.add_argument(
        "--cat062-udp",
        default=None,
        metavar="HOST:PORT",
        help="Also send every TrackBatch as CAT062 UDP datagrams to HOST:PORT",
    )
    cat.add_argument("--cat062-sac", type=int, default=0, help="I062/010 SAC (default: 0)")
    cat.add_argument("--cat062-sic", type=int, default=1, help="I062/010 SIC (default: 1)")
    add_transport_arguments(p)
    p.set_defaults(func=run)


def tracker_config(args: argparse.Namespace):
    """The TrackerConfig: defaults < TOML [tracker] < SKYFUSE_TRACKER_* < flags."""

    overrides = {}
    for item in getattr(args, "tracker_set", []):
        if "=" not in item:
            raise ConfigError(f"tracker-set {item!r} is not FIELD=VALUE")
    overrides.update(parse_key_values(getattr(args, "tracker_set", [])))
    if hasattr(args, "tracker"):
        overrides["tracker"] = args.tracker
    return build_config(
        _tracker_config_model(),
        None,
        toml_path=getattr(args, "config", None),
        section="tracker",
        env_prefix="SKYFUSE_TRACKER_",
        overrides=overrides,
    )


def make_pipeline_factory(tracker_cfg, fusion_id: str, *, assumed_altitude: float | None = None):
    """``frame -> pipeline``: the conversion + tracker + TrackBatch code path shared with
    ``skyfuse track``."""
    from skyfuse.services.fusion.pipeline import TrackPipeline

    def factory(frame):
        return TrackPipeline(
            frame, tracker_cfg, fusion_id=fusion_id, assumed_altitude=assumed_altitude
        )

    return factory


def run(args: argparse.Namespace) -> int:
    cfg = build_config(
        FusionConfig, args, toml_path=args.config, section="fusion", env_prefix="SKYFUSE_FUSION_"
    )
    tracker_cfg = tracker_config(args)
    tcfg = transport_config(args, toml_path=args.config)
    core = FusionCore(
        cfg,
        make_pipeline_factory(tracker_cfg, cfg.fusion_id, assumed_altitude=cfg.assumed_altitude),
    )
    cat062 = None
    if getattr(args, "cat062_udp", None):
        from skyfuse.services.cli.cmd_cat062 import Cat062UdpSender

        try:
            cat062 = Cat062UdpSender(args.cat062_udp, sac=args.cat062_sac, sic=args.cat062_sic)
        except ValueError as e:
            raise ConfigError(str(e)) from None
    stop = StopFlag().install()
    try:
        with open_session(tcfg) as session:
            serve(session, core, stop, cat062=cat062)
    except TransportError as e:
        log.error("%s", e)
        return EXIT_FAILED
    finally:
        if cat062 is not None:
            log.info("cat062 output: %s", dict(cat062.stats))
            cat062.close()
    return EXIT_OK


def serve(session, core: FusionCore, stop, *, duration: float | None = None, cat062=None) -> None:
    """The service loop: until ``stop`` is set (or ``duration`` s elapse). ``cat062``: a
    :class:`services.cmd_cat062.Cat062UdpSender` that also gets every output."""
    fid = core.cfg.fusion_id
    pub_tracks = declare_publisher(session, keys.fusion_tracks(fid))
    pub_events = declare_publisher(session, keys.fusion_events(fid))
    pub_status = declare_publisher(session, keys.fusion_status(fid))
    snapshot_key = keys.fusion_snapshot(fid)
    latest = {"payload": None}

    def answer_snapshot(q) -> None:
        payload = latest["payload"]
        if payload is not None:
            q.reply(snapshot_key, payload)
        else:
            q.reply_err(b"no tracks yet")

    queryable = session.declare_queryable(snapshot_key, answer_snapshot)
    inbox = Inbox(capacity=core.cfg.queue)
    inbox.subscribe(session, keys.ALL_SITES, "site")
    inbox.subscribe(session, keys.ALL_PLOTS, "plots")
    inbox.subscribe_liveliness(session, keys.ALL_ALIVE, "alive")
    # sites published before we joined: ask the sensors' queryables
    for key, payload in query(session, keys.ALL_SITES, timeout=1.0):
        core.on_site_payload(key, payload)
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
                pub_status.put(core.status().to_json_bytes())
    finally:
        token.undeclare()
        inbox.close()
        # apply what was already received, but never past the shutdown deadline
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
        st = core.status()
        pub_status.put(st.to_json_bytes())
        queryable.undeclare()
        lat = st.latency_ms
        log.info(
            "fusion %s: %d batches (%d plots) in, %d cycles, %s confirmed tracks; latency "
            "p50 %s ms p99 %s ms; rejected %s",
            fid,
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
