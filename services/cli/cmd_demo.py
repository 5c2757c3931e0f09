"""``skyfuse demo [--radars N] [--targets N] [--duration S] [--speed X] [--listen EP]
[--out FILE.mcap] [--json FILE] [--foxglove] [--tracker KIND] [--particles N]``: run N
simulated radars, the fusion service and the recorder as separate processes over Zenoh
on loopback, show live progress, stop everything cleanly and print a summary (plots,
confirmed tracks, GOSPA against truth, latency, messages recorded) with a PNG of tracks
against truth.

While it runs, other programs can join at the ``--listen`` endpoint, e.g.
``skyfuse tracks --connect tcp/127.0.0.1:PORT``.

Exit codes: 0 done, 1 a service failed or the recording is unusable, 2 bad usage,
130 interrupted (the summary of what was recorded is still written)."""

from __future__ import annotations

import argparse
import json
import logging
import sys
import tempfile
import time
from pathlib import Path

from pydantic import ValidationError
from skyfuse.schemas import Status, TrackBatch, TrackPicture, TrackStatus, keys
from skyfuse.services.cli.service_command import add_service_parser
from skyfuse.services.evaluation.demo import (
    Child,
    DemoConfig,
    identity_lines,
    plot_tracks_vs_truth,
    report_recording,
)
from skyfuse.services.fusion.kernel_cache import timed_load
from skyfuse.services.runtime.config import ConfigError, add_json_argument, build_config
from skyfuse.services.runtime.lifecycle import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, StopFlag
from skyfuse.services.runtime.transport import (
    Inbox,
    TransportConfig,
    TransportError,
    check_endpoint,
    declare_liveliness,
    loopback_endpoint,
    open_session,
    service_alive_key,
    wait_for_tokens,
)

log = logging.getLogger("skyfuse.demo")


def register(sub: argparse._SubParsersAction) -> None:
    p = add_service_parser(
        sub, "demo", "run sensors, fusion and recorder as processes over Zenoh on loopback",
        __doc__, DemoConfig, tables=None, transport=False, skip=("json_out",),
    )  # fmt: skip
    add_json_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    cfg = build_config(DemoConfig, args)
    if cfg.listen is not None:
        try:
            check_endpoint(cfg.listen)
        except ValueError as e:
            raise ConfigError(f"listen: {e}") from None
    from skyfuse.fusion.sim import build_scenario

    try:
        sc = build_scenario(
            cfg.scenario, seed=cfg.seed, duration=cfg.duration, targets=cfg.targets,
            radars=scenario_radars(cfg),
        )  # fmt: skip
    except (ValueError, TypeError) as e:
        raise ConfigError(str(e)) from None
    workdir = cfg.workdir or Path(tempfile.mkdtemp(prefix="skyfuse-demo-"))
    workdir.mkdir(parents=True, exist_ok=True)
    out = cfg.out or workdir / "demo.mcap"
    out.parent.mkdir(parents=True, exist_ok=True)
    png = cfg.png or out.with_suffix(".png")
    listen = cfg.listen or loopback_endpoint()
    stop = StopFlag(grace=30.0).install()
    live = sys.stderr.isatty() if cfg.live is None else cfg.live
    # the tracker kernels into their cache here, with progress, before the fusion
    # process starts (it then loads them in a fraction of a second)
    timed_load(log)
    try:
        with open_session(TransportConfig(mode="peer", listen=[listen])) as session:
            interrupted, failed, children = orchestrate(
                session, cfg, sc, listen, out, workdir, stop, live
            )
    except TransportError as e:
        log.error("%s", e)
        return EXIT_FAILED
    if not out.is_file():
        log.error("no recording was written (%s)", out)
        return EXIT_FAILED
    ev = report_recording(out, cfg.gospa_c)
    ev.summary.update(
        {
            "scenario": cfg.scenario,
            "seed": cfg.seed,
            "duration_s": cfg.duration,
            "speed": cfg.speed,
            "targets": cfg.targets,
            "tracker": cfg.tracker,
            "particles": cfg.particles,
            "endpoint": listen,
            "logs": str(workdir),
            "png": str(png),
            "interrupted": interrupted,
            "failed_services": failed,
            "services": {c.name: {"exit_code": c.rc, "stop_s": c.stop_s} for c in children},
        }
    )
    try:
        plot_tracks_vs_truth(ev, png, f"skyfuse demo ({cfg.radars} radars)")
    except Exception as e:  # the plot is a bonus; the summary must still be written
        log.warning("could not write the PNG: %s", e)
    if cfg.json_out is not None and str(cfg.json_out) == "-":
        print(json.dumps(ev.summary, indent=2))
    else:
        if cfg.json_out is not None:
            cfg.json_out.parent.mkdir(parents=True, exist_ok=True)
            cfg.json_out.write_text(json.dumps(ev.summary, indent=2) + "\n")
        print_summary(ev.summary)
    if failed:
        return EXIT_FAILED
    return EXIT_INTERRUPTED if interrupted else EXIT_OK


def scenario_radars(cfg: DemoConfig) -> int:
    """The scenario's ``radars`` parameter: it has at least 3; the demo runs the first N."""
    return max(cfg.radars, 3)


def fusion_arguments(cfg: DemoConfig, frame, common: list[str]) -> list[str]:
    """``skyfuse fusion`` arguments of the demo's fusion process: the scenario's system
    frame, the tracker kind and its particles per track (``--particles``, the flag of
    ``skyfuse fusion`` / ``track`` / ``eval``; used by ipf and lmipf only), then ``common``
    (the Zenoh connection)."""
    return [
        "fusion", "--fusion-id", "demo", "--reorder-wait", str(cfg.reorder_wait),
        "--frame-kind", frame.kind.value, "--frame-lat0", repr(frame.lat0), "--frame-lon0",
        repr(frame.lon0), "--tracker", cfg.tracker, "--particles", str(cfg.particles),
        *common,
    ]  # fmt: skip


def orchestrate(session, cfg: DemoConfig, sc, listen, out, workdir, stop, live):
    """Start, watch and stop the services; return (interrupted, failed service names,
    the children)."""
    run = _DemoRun(session, cfg, sc, listen, out, workdir, stop, live)
    try:
        if run.start_services() and run.sensors_up():
            run.watch()
            run.drain()
    finally:
        run.shutdown()
    return run.interrupted, run.failed, run.children


class _DemoRun:
    """The phases of :func:`orchestrate`: recorder and fusion up → sensors up → watch
    until the sensors end → let the fusion catch up → stop everything."""

    def __init__(self, session, cfg: DemoConfig, sc, listen, out, workdir, stop, live) -> None:
        self.session, self.cfg, self.stop, self.workdir = session, cfg, stop, workdir
        self.state = Path(tempfile.mkdtemp(prefix="state-", dir=workdir))  # fresh per run
        self.radars = [s.radar_id for s in sc.sites][: cfg.radars]
        self.common = ["--connect", listen, "--no-multicast"]
        self.recorder = Child(
            "recorder",
            ["record", "--out", str(out), "--stats", str(workdir / "recorder.json"), *self.common],
            workdir / "recorder.log",
        )
        self.fusion = Child(
            "fusion", fusion_arguments(cfg, sc.frame, self.common), workdir / "fusion.log"
        )
        self.inbox = Inbox(capacity=10_000)
        for key, tag in (
            (f"{keys.PREFIX}/fusion/*/status", "status"),
            (f"{keys.PREFIX}/service/*/status", "status"),
            (f"{keys.PREFIX}/fusion/*/tracks", "tracks"),
        ):
            self.inbox.subscribe(session, key, tag)
        self.fox = _foxglove(cfg) if cfg.foxglove else None
        if self.fox is not None:
            self.inbox.subscribe(session, keys.SIM_TRUTH, "truth")
        self.children = [self.recorder, self.fusion]
        self.sensors: list[Child] = []
        self.failed: list[str] = []
        self.interrupted = False
        self.view = _View(cfg, self.radars, live)
        self.go = None
        self.listen = listen

    def _came_up(self, names: list[str], children: list[Child], what: str) -> bool:
        keys_ = [service_alive_key(n) for n in names]
        missing = wait_for_tokens(self.session, keys_, self.cfg.start_timeout, self.stop)
        if missing and not self.stop.is_set():
            self.failed += [c.name for c in children if c.poll() is not None] or ["startup"]
            log.error("%s did not come up: %s", what, missing)
            return False
        return True

    def start_services(self) -> bool:
        """Recorder, fusion and the sensors start together (a sensor publishes nothing
        before the demo's "go" token, declared once everything is up: its start-up runs
        while the services start); True once the services are up."""
        for c in self.children:
            c.start(None, self.state)  # children inherit the working directory
        log.info("demo network on %s; logs in %s", self.listen, self.workdir)
        self.start_sensors()
        return self._came_up(["recorder", "fusion"], [self.recorder, self.fusion], "services")

    def start_sensors(self) -> None:
        """Sensors load the scenario, declare their ready tokens and wait for the demo's
        "go" token (:meth:`sensors_up`); then they all start within a poll interval
        (~0.1 s) of each other."""
        cfg = self.cfg
        scen = [
            "--scenario", cfg.scenario, "--seed", str(cfg.seed), "--duration", str(cfg.duration),
            "--targets", str(cfg.targets), "--param", f"radars={scenario_radars(cfg)}",
        ]  # fmt: skip
        for i, r in enumerate(self.radars):
            extra = ["--truth"] if i == 0 else []
            s = Child(
                f"sensor-{r}",
                [
                    "sensor", "--radar", r, *scen, "--speed", str(cfg.speed),
                    "--wait-for", "demo", "--wait-timeout", str(cfg.start_timeout), *extra,
                    *self.common,
                ],
                self.workdir / f"sensor-{r}.log",
            )  # fmt: skip
            s.start(None, self.state)
            self.sensors.append(s)
        self.children += self.sensors

    def sensors_up(self) -> bool:
        """Wait for the sensors' ready tokens, then declare "go"."""
        names = [f"sensor-{r}" for r in self.radars]
        if not self._came_up(names, self.sensors, "sensors"):
            return False
        self.go = declare_liveliness(self.session, service_alive_key("demo"))
        self.view.start(time.time())
        return True

    def _feed(self) -> None:
        for item in self.inbox.drain(2000):
            self.view.feed(item, self.fox)
        self.view.refresh()

    def watch(self) -> None:
        """Until the sensors have finished (or a service died, or a stop)."""
        while not self.stop.is_set():
            self._feed()
            dead = [c for c in (self.recorder, self.fusion) if c.poll() is not None]
            if dead:
                self.failed += [c.name for c in dead]
                log.error("%s exited early:\n%s", dead[0].name, dead[0].tail())
                break
            if all(s.poll() is not None for s in self.sensors):
                self.failed += [s.name for s in self.sensors if s.rc != 0]
                break
            self.stop.wait(0.2)
        self.interrupted = self.stop.is_set()

    def drain(self) -> None:
        """Let the fusion service catch up: wait until it has taken in every batch the
        sensors published (their final Status says how many) and emptied its buffer."""
        timeout = self.cfg.drain_timeout if not self.interrupted else 1.0
        end = time.monotonic() + timeout
        while time.monotonic() < end and not (self.interrupted and self.stop.wait(0)):
            self._feed()
            if self.view.fusion_caught_up(self.radars) or self.fusion.poll() is not None:
                return
            time.sleep(0.1)
        if not self.interrupted:
            log.warning("the fusion service did not catch up within %.0f s", timeout)

    def shutdown(self) -> None:
        if self.go is not None:
            self.go.undeclare()
        for c in self.sensors:
            c.terminate()
        self.fusion.terminate()
        time.sleep(0.3)
        for item in self.inbox.drain(10_000):
            self.view.feed(item, self.fox)
        self.recorder.terminate()
        self.inbox.close()
        self.view.stop()
        if self.fox is not None:
            self.fox["server"].stop()
        for c in self.children:
            if c.rc not in (0, None):
                if c.name not in self.failed:
                    self.failed.append(c.name)
                log.error("%s exited with %s:\n%s", c.name, c.rc, c.tail())
            if c.stop_s is not None:
                log.info("%s stopped in %.2f s (exit %s)", c.name, c.stop_s, c.rc)


def _foxglove(cfg: DemoConfig):
    import foxglove
    from foxglove.channels import LocationFixesChannel

    server = foxglove.start_server(host="127.0.0.1", port=cfg.foxglove_port)
    log.info("Foxglove WebSocket on ws://127.0.0.1:%d (open it in Foxglove)", cfg.foxglove_port)
    return {
        "server": server,
        "tracks": LocationFixesChannel("/foxglove/tracks"),
        "truth": LocationFixesChannel("/foxglove/truth"),
    }


class _View:
    """Live progress (rich) from the services' Status messages; log lines without a tty."""

    def __init__(self, cfg: DemoConfig, radars: list[str], live: bool) -> None:
        self.cfg = cfg
        self.radars = radars
        self.live_enabled = live
        self.status: dict[str, Status] = {}
        self.tracks: TrackBatch | None = None
        self._picture = TrackPicture()  # the feed's deltas and fulls rebuilt
        self.start_at = None
        self._live = None
        self._last_log = 0.0

    def start(self, start_at: float) -> None:
        self.start_at = start_at
        if self.live_enabled:
            from rich.console import Console
            from rich.live import Live

            self._live = Live(self._render(), console=Console(stderr=True), refresh_per_second=4)
            self._live.start()

    def feed(self, item, fox) -> None:
        try:
            if item.tag == "status":
                st = Status.from_json_bytes(item.payload)
                self.status[st.service_id] = st
            elif item.tag == "tracks":
                self._picture.apply(TrackBatch.from_json_bytes(item.payload))
                self.tracks = self._picture.batch()
                if fox is not None:
                    _fox_tracks(fox, self.tracks)
            elif item.tag == "truth" and fox is not None:
                from skyfuse.schemas import Truth
                from skyfuse.services.recording.recorder import location_fixes

                tr = Truth.from_json_bytes(item.payload)
                fox["truth"].log(location_fixes(tr.time, "truth", tr.lat, tr.lon, tr.alt, _green()))
        except ValidationError:
            pass

    def fusion_caught_up(self, radars: list[str]) -> bool:
        """Whether the fusion service has received every batch the sensors reported as
        published (final sensor Status) and has nothing left in its reorder buffer."""
        fus = self.status.get("demo")
        sensors = [self.status.get(f"sensor-{r}") for r in radars]
        if fus is None or any(s is None for s in sensors):
            return False
        published = sum(s.counters.get("batches", 0) for s in sensors)
        return (
            fus.counters.get("batches_received", 0) >= published
            and fus.counters.get("queued", 0) == 0
        )

    def _render(self):
        from rich.table import Table

        elapsed = 0.0 if self.start_at is None else max(0.0, time.time() - self.start_at)
        sim = min(self.cfg.duration, elapsed * self.cfg.speed)
        t = Table(title=f"skyfuse demo — simulated {sim:5.0f} / {self.cfg.duration:.0f} s")
        for c in ("radar", "alive", "batches", "plots", "plots/s"):
            t.add_column(c, justify="right")
        fus = self.status.get("demo")
        health = {r.radar_id: r for r in (fus.radars if fus else [])}
        for r in self.radars:
            h = health.get(r)
            t.add_row(
                r,
                "yes" if h and h.alive else "-",
                str(h.batches if h else 0),
                str(h.plots if h else 0),
                f"{h.plots_per_s:.0f}" if h else "0",
            )
        lat = fus.latency_ms if fus else None
        rec = self.status.get("recorder")
        t.caption = (
            f"tracks confirmed {fus.tracks_confirmed if fus else '-'} / "
            f"{fus.tracks_total if fus else '-'}   latency p50 "
            f"{_ms(lat.p50 if lat else None)} p99 {_ms(lat.p99 if lat else None)}   "
            f"recorded {rec.counters.get('messages', 0) if rec else 0} messages"
        )
        return t

    def refresh(self) -> None:
        if self._live is not None:
            self._live.update(self._render())
        elif time.monotonic() - self._last_log > 5.0:
            self._last_log = time.monotonic()
            fus = self.status.get("demo")
            if fus is not None:
                log.info(
                    "fusion: %s plots in, %s confirmed tracks, latency p50 %s",
                    fus.counters.get("plots_in", 0),
                    fus.tracks_confirmed,
                    _ms(fus.latency_ms.p50 if fus.latency_ms else None),
                )

    def stop(self) -> None:
        if self._live is not None:
            self._live.update(self._render())
            self._live.stop()
            self._live = None


def _green():
    from foxglove import messages as fg

    return fg.Color(r=0.1, g=0.7, b=0.1, a=1.0)


def _fox_tracks(fox, batch: TrackBatch) -> None:
    from foxglove import messages as fg
    from skyfuse.services.recording.recorder import location_fixes

    conf = [t for t in batch.tracks if t.status == TrackStatus.CONFIRMED]
    fox["tracks"].log(
        location_fixes(
            batch.time,
            batch.fusion_id,
            [t.lat for t in conf],
            [t.lon for t in conf],
            [t.alt or 0.0 for t in conf],
            fg.Color(r=0.1, g=0.4, b=1.0, a=1.0),
        )
    )


def _ms(v) -> str:
    return "-" if v is None else f"{v:.0f} ms"


def print_summary(s: dict) -> None:
    lat = s.get("latency_ms") or {}
    lines = [
        f"skyfuse demo: {len(s['radars'])} radars, {s['targets_truth']} aircraft, "
        f"{s['duration_s']:.0f} s at x{s['speed']:g}",
        f"  plots published/recorded : {s['plots_recorded']} in {s['plot_batches_recorded']} "
        f"batches (sensors published {s['plot_batches_published']} batches)",
        f"  fusion                   : {s['fusion_plots_in']} plots in, {s['fusion_cycles']} "
        f"cycles, rejected {s['fusion_rejected'] or 'none'}",
        f"  confirmed tracks         : {s['confirmed_tracks_final']} at the end "
        f"({s['confirmed_track_ids']} ids over the run); targets confirmed "
        f"{s['targets_confirmed']} of {s['targets_detectable']} detectable",
        f"  GOSPA (c={s['gospa_c_m']:.0f} m)        : mean {_num(s['gospa_mean_m'])} m, "
        f"second half {_num(s['gospa_mean_second_half_m'])} m, final {_num(s['gospa_final_m'])} m",
        f"  latency plot→track       : p50 {_num(lat.get('p50'))} ms, "
        f"p99 {_num(lat.get('p99'))} ms",
        f"  messages recorded        : {s['messages_recorded']} in {s['recording']}",
        f"  plot                     : {s['png']}",
        *identity_lines(s),
    ]
    print("\n".join(lines))


def _num(v) -> str:
    return "-" if v is None else f"{v:.0f}"
