"""Sustained plots/s, latency and memory of one ``skyfuse fusion`` process fed over Zenoh
on loopback by several publisher processes, and the offline ``skyfuse track`` speed on
the same plots in the same run (the live/offline ratio is the figure to watch): the
rate of the whole ``skyfuse track`` run up to its last step (reading the recording,
writing its output, the per-step scoring), and the rate of its tracker steps alone
(conversion, tracker, output message: the live service's work per batch),
``live_over_offline`` and ``live_over_offline_steps``.

For each offered rate R (plots/s): the ``regional`` scenario (``--radars`` radars,
``--targets`` aircraft) is simulated for ``--seconds`` × speed simulated seconds into an
MCAP file, where speed makes its plot rate R; ``skyfuse track`` runs on that file (offline
plots/s); then one ``skyfuse replay --radars ID --speed speed`` process per radar
publishes it to one ``skyfuse fusion`` (same frame as ``skyfuse track``: stereographic at
the sites' mean), and this process follows the fusion Status and the track feed. The
script reports the offered rate, the rate the fusion sustained (plots applied / time to
apply them, or up to the ``--drain`` limit after the publishers finished; then the
backlog is reported), latency percentiles from the publisher's sweep-end stamp to the
publication of the delta that contains the batch (fusion Status, over every batch; it
includes the reorder wait), the largest backlog and whether Status said "behind", the
fusion's resident memory (VmRSS, start of the level and maximum), feed message counts
(delta/full), and the load average. CPU (utime + stime from ``/proc/PID/stat``) over the
level: of the fusion process, of its main thread (the single thread that decodes,
converts and tracks: its plots per CPU second is the capacity of one dedicated core),
and of all publisher processes (which compete with the fusion for the cores on a small
machine); ``fusion_cpu_share`` = fusion / (fusion + publishers). ``batches_late_applied``:
batches that arrived behind the service time and went through the tracker's
out-of-sequence update (publishers started a few ms apart are seconds apart in data time
at high speed factors; each such batch costs more than an in-order one).

    python benchmarks/service_pipeline.py [--rates 2000,5000,20000] [--seconds 10]
        [--targets 1000] [--radars 6] [--sectors 16] [--reorder-wait 0.2]
        [--max-backlog S] [--coalesce-max-deg DEG] [--bulk-max N] [--delta-split-s S|off]
        [--json out.json]
        [--profile DIR]    # py-spy collapsed stacks of the fusion process per level
        [--publisher-cpus 1]  # the replays on core 1 only (as radars on other hosts)
        [--no-offline]     # skip the offline comparison (long soak runs: RSS over time)
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from skyfuse.fusion.sim import Simulator, build_scenario  # noqa: E402
from skyfuse.schemas import Status, keys  # noqa: E402
from skyfuse.services.evaluation.demo import Child, python_env  # noqa: E402
from skyfuse.services.runtime.transport import (  # noqa: E402
    Inbox,
    TransportConfig,
    declare_liveliness,
    loopback_endpoint,
    open_session,
    service_alive_key,
    wait_for_tokens,
)


def level_scenario(a, duration: float):
    """The scenario of a level: ``regional`` with ``--radars`` radars, ``--sectors``
    sectors per revolution and ``--targets`` aircraft (``--traffic mixed|steady``: its
    own routes); with ``--scan-period T`` every radar turns in T s (phases kept as
    fractions of the revolution); ``--traffic straight``: the aircraft fly straight and
    level for the whole run from uniform positions in the traffic area (170 km around the
    centre), uniform headings, 150–240 m/s, 3,000–12,000 m, 80 % with a Mode-S address.
    The plots always come from the simulator's WGS-84 geometry (pymap3d)."""
    import dataclasses

    traffic = getattr(a, "traffic", "mixed")
    sc = build_scenario(
        "regional", seed=a.seed, duration=duration, targets=a.targets, radars=a.radars,
        traffic="steady" if traffic == "steady" else "mixed",
        n_sectors=getattr(a, "sectors", 16),
    )  # fmt: skip
    period = getattr(a, "scan_period", None)
    if period is not None:
        sensors = [
            dataclasses.replace(
                c, site=c.site.model_copy(update={"scan_period": period}),
                phase=period * c.phase / c.site.scan_period,
            )
            for c in sc.sensors
        ]  # fmt: skip
        sc = dataclasses.replace(sc, sensors=sensors, sites=[c.site for c in sensors])
        sc = dataclasses.replace(sc, truth_period=period)
    if traffic == "straight":
        sc = dataclasses.replace(sc, targets=straight_targets(a.targets, a.seed, duration))
    return sc


def straight_targets(n: int, seed: int, duration: float):
    """n aircraft in straight and level flight for ``duration`` s (see level_scenario)."""
    from skyfuse.fusion.sim.trajectories import TargetSet, TrajectoryBuilder

    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(77,)))
    r = 170_000.0 * np.sqrt(rng.random(n))
    phi, heading = rng.uniform(0, 2 * np.pi, n), rng.uniform(0, 2 * np.pi, n)
    speed, alt = rng.uniform(150.0, 240.0, n), rng.uniform(3000.0, 12000.0, n)
    builders = [
        TrajectoryBuilder(0.0, (r[i] * np.cos(phi[i]), r[i] * np.sin(phi[i]), alt[i]),
                          (speed[i] * np.sin(heading[i]), speed[i] * np.cos(heading[i]), 0.0))
        .straight(duration)
        for i in range(n)
    ]  # fmt: skip
    mode_s = np.where(rng.random(n) < 0.8, 1 + rng.choice((1 << 24) - 1, n, replace=False), -1)
    return TargetSet.from_builders(
        builders, t_birth=np.zeros(n), t_death=np.full(n, np.inf), mode_s=mode_s,
        mode_3a=np.where(mode_s > 0, rng.integers(0o1000, 0o7000, n), -1),
    )  # fmt: skip


def custom_load(a) -> bool:
    """Whether the level's scenario differs from ``skyfuse simulate --scenario regional``."""
    return getattr(a, "scan_period", None) is not None or getattr(a, "traffic", "") == "straight"


def sim_plot_rate(a, duration: float = 30.0) -> float:
    """Plots per simulated second of the scenario (all radars)."""
    sc = level_scenario(a, duration)
    n = sum(len(ev.message.time) for ev in Simulator(sc, seed=a.seed).run() if ev.kind == "plots")
    return n / duration


def write_recording(sc, seed: int, path: Path) -> None:
    """The scenario's messages (sites, plot batches, truth) into an MCAP recording."""
    from skyfuse.services.recording.mcap_io import RecordingWriter

    with RecordingWriter(path, metadata={"scenario": sc.name, "seed": str(seed)}) as writer:
        for ev in Simulator(sc, seed=seed).run():
            writer.write(ev.topic, ev.message, ev.time)


def skyfuse_cli(*args: str) -> None:
    cmd = [sys.executable, "-m", "skyfuse.services.cli", "--log-level", "WARNING"]
    subprocess.run([*cmd, *args], check=True, env=python_env(), stdout=subprocess.DEVNULL)


def make_level_files(rate: float, speed: float, a, work: Path) -> tuple[Path, dict]:
    """The level's recording, and ``skyfuse track`` on it (its JSON summary)."""
    rec, js = work / f"level-{rate:.0f}.mcap", work / f"track-{rate:.0f}.json"
    if custom_load(a):
        write_recording(level_scenario(a, round(a.seconds * speed, 1)), a.seed, rec)
    else:
        skyfuse_cli(
            "simulate", "--scenario", "regional", "--seed", str(a.seed), "--duration",
            f"{a.seconds * speed:.1f}", "--targets", str(a.targets), "--param",
            f"radars={a.radars}", "--param", f"traffic={getattr(a, 'traffic', 'mixed')}",
            "--param", f"n_sectors={getattr(a, 'sectors', 16)}", "--out", str(rec),
            "--no-progress",
        )  # fmt: skip
    if a.no_offline:
        return rec, recording_facts(rec)
    skyfuse_cli("track", str(rec), "--out", str(work / "offline.mcap"), "--json", str(js),
                "--no-progress")  # fmt: skip
    return rec, json.loads(js.read_text())


def recording_facts(rec: Path) -> dict:
    """What the level needs from ``skyfuse track``'s summary, without running it
    (``--no-offline``): frame (stereographic at the sites' mean), radars, batches, plots."""
    from skyfuse.schemas import PlotBatch, RadarSite
    from skyfuse.services.recording.mcap_io import iter_recording

    sites, batches, plots = {}, 0, 0
    for r in iter_recording(rec):
        if isinstance(r.message, RadarSite):
            sites[r.message.radar_id] = r.message
        elif isinstance(r.message, PlotBatch):
            batches, plots = batches + 1, plots + len(r.message)
    lat0 = float(np.mean([s.lat for s in sites.values()]))
    lon0 = float(np.mean([s.lon for s in sites.values()]))
    return {
        "frame": {"lat0": lat0, "lon0": lon0},
        "radars": sorted(sites),
        "batches": batches,
        "plots_processed": plots,
        "timing": {"plots_per_s": None, "plots_per_s_steps": None},
    }


def rss_mb(pid: int) -> float | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        return None
    return None


_TICK = os.sysconf("SC_CLK_TCK")


def cpu_s(pid: int, thread: int | None = None) -> float | None:
    """CPU seconds (utime + stime, fields 14 and 15 of ``/proc/PID/stat``, all threads) of
    a process, or of one of its threads (``/proc/PID/task/TID/stat``); None once it is
    gone. A zombie (exited, not yet reaped) still reports its final times."""
    path = f"/proc/{pid}/stat" if thread is None else f"/proc/{pid}/task/{thread}/stat"
    try:
        fields = Path(path).read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    return (int(fields[11]) + int(fields[12])) / _TICK


class CpuMeter:
    """CPU seconds of the fusion process (whole, and its main thread, the one that runs
    the tracker) and of the publisher processes over the level. A publisher's last
    figure is read when it has exited but is not yet reaped (``waitid`` with
    ``WNOWAIT``), so its whole run is counted."""

    def __init__(self, fusion_pid: int, pubs) -> None:
        self.fusion_pid, self.pubs = fusion_pid, pubs
        self.f0 = cpu_s(fusion_pid) or 0.0
        self.m0 = cpu_s(fusion_pid, fusion_pid) or 0.0
        self.pub_cpu = {c.name: cpu_s(c.proc.pid) or 0.0 for c in pubs}
        self.fusion = self.main = 0.0

    def running(self, c) -> bool:
        """Whether publisher ``c`` still runs; record its CPU seconds (final at exit)."""
        pid = c.proc.pid
        exited = c.rc is not None or os.waitid(
            os.P_PID, pid, os.WEXITED | os.WNOHANG | os.WNOWAIT
        ) is not None  # fmt: skip
        if c.rc is None and (v := cpu_s(pid)) is not None:
            self.pub_cpu[c.name] = v
        return not exited or c.poll() is None

    def stop_fusion(self) -> None:
        self.fusion = (cpu_s(self.fusion_pid) or 0.0) - self.f0
        self.main = (cpu_s(self.fusion_pid, self.fusion_pid) or 0.0) - self.m0

    def result(self, applied: int, wall: float) -> dict:
        pub = sum(self.pub_cpu.values())
        r3 = lambda v: round(v, 3)  # noqa: E731
        return {
            "fusion_cpu_s": r3(self.fusion),
            "fusion_main_thread_cpu_s": r3(self.main),
            "publishers_cpu_s": r3(pub),
            "fusion_cores": r3(self.fusion / wall) if wall > 0 else None,
            "fusion_cpu_share": r3(self.fusion / (self.fusion + pub)) if pub else None,
            "plots_per_fusion_cpu_s": round(applied / self.fusion, 1) if self.fusion else None,
            "plots_per_main_thread_cpu_s": round(applied / self.main, 1) if self.main else None,
        }


class Follower:
    """Status of every service and counts of the fusion feed, from this process."""

    def __init__(self, session, fusion_pid: int) -> None:
        self.inbox = Inbox()
        self.inbox.subscribe(session, f"{keys.PREFIX}/fusion/bench/*", "fusion")
        self.inbox.subscribe(session, f"{keys.PREFIX}/service/*/status", "status")
        self.status: dict[str, Status] = {}
        self.feed = {"delta": 0, "full": 0}
        self.pid = fusion_pid
        self.rss: list[float] = []
        self.max_backlog = 0
        self.behind_seen = False
        self.series: list[tuple[float, float | None, Status]] = []
        """``(monotonic time, fusion RSS MB, Status)`` of every fusion Status received."""

    def pump(self, timeout: float) -> None:
        item = self.inbox.get(timeout)
        while item is not None:
            if item.key.endswith("/tracks"):
                self.feed["full" if b'"kind":"full"' in item.payload[:80] else "delta"] += 1
            elif item.key.endswith("/status"):
                try:
                    st = Status.from_json_bytes(item.payload)
                except ValueError:  # not a service's (benchmarks/hostile_soak.py's fuzzer)
                    item = self.inbox.get(0) if self.inbox.qsize() else None
                    continue
                self.status[st.service_id] = st
                if st.service_id == "bench" and st.backlog is not None:
                    self.max_backlog = max(self.max_backlog, st.backlog.batches)
                    self.behind_seen |= st.backlog.behind
                    if (r := rss_mb(self.pid)) is not None:
                        self.rss.append(r)
                    self.series.append((time.monotonic(), r, st))
            item = self.inbox.get(0) if self.inbox.qsize() else None

    def caught_up(self, published: int) -> bool:
        fs = self.status.get("bench")
        if fs is None or fs.counters.get("batches_received", 0) < published:
            return False
        return fs.counters.get("queued", 0) == 0


def sites_toml(rec: Path, work: Path) -> Path:
    """The recording's radar sites as the fusion's configured sites (``[[fusion.sites]]``):
    a replay publishes each site once at its start, which a fusion service that has not
    yet been discovered by the publisher misses."""
    import tomli_w
    from skyfuse.schemas import RadarSite
    from skyfuse.services.recording.mcap_io import iter_recording

    sites = {r.message.radar_id: r.message for r in iter_recording(rec)
             if isinstance(r.message, RadarSite)}  # fmt: skip
    path = work / "fusion.toml"
    rows = [s.model_dump(mode="json", exclude_none=True) for s in sites.values()]
    path.write_text(tomli_w.dumps({"fusion": {"sites": rows}}))
    return path


START_LEAD_S = 4.0
"""The replays' common start is this long after they are launched (start-up, tokens)."""


def start_replays(pubs, state_home: Path, cpus: set[int] | None = None) -> float:
    """Launch the replay processes with one common ``--start-at``: their own start-ups
    differ by tens of ms, which is seconds of data time at high speed (the reorder buffer
    would hold the batches of the early ones until the late ones catch up). Returns the
    common start on the monotonic clock (the start of the level's timing). ``cpus``: the
    cores the replays may run on (``--publisher-cpus``; set right after the launch, before
    the child opens its Zenoh session, so its runtime threads inherit it)."""
    start_at = round(time.time() + START_LEAD_S, 3)
    t0 = time.monotonic() + (start_at - time.time())
    for c in pubs:
        c.args += ["--start-at", f"{start_at:.3f}"]
        c.start(state_home=state_home)
        if cpus:
            os.sched_setaffinity(c.proc.pid, cpus)
    return t0


def parse_cpus(text: str) -> set[int]:
    """``--publisher-cpus`` ("1" or "1,2"): core numbers this process may use."""
    cpus = {int(v) for v in text.split(",")}
    if not cpus <= os.sched_getaffinity(0):
        raise argparse.ArgumentTypeError(f"{text}: this process may use {os.sched_getaffinity(0)}")
    return cpus


def start_children(
    rec: Path, speed: float, radars: list[str], frame, a, work: Path, rate, fusion_extra=()
):
    """The fusion process (id ``bench``) and one replay process per radar (not started);
    ``fusion_extra``: more ``skyfuse fusion`` flags."""
    ep = loopback_endpoint()
    fusion = Child(
        "fusion",
        [
            "--log-level", "WARNING", "fusion", "--config", str(sites_toml(rec, work)),
            "--fusion-id", "bench", "--reorder-wait",
            str(a.reorder_wait), "--frame-kind", "stereographic", "--frame-lat0",
            repr(frame[0]), "--frame-lon0", repr(frame[1]), "--status-interval", "0.5",
            "--latency-window", "1000000", "--connect", ep, *fusion_extra,
        ],
        work / f"fusion-{rate:.0f}.log",
    )  # fmt: skip
    replay = ["--log-level", "WARNING", "replay", str(rec), "--speed", f"{speed:.4f}"]
    replay += ["--wait-for", "bench", "--wait-timeout", "60", "--connect", ep]
    pubs = [
        Child(f"replay-{r}", [*replay, "--radars", r], work / f"replay-{r}-{rate:.0f}.log")
        for r in radars
    ]
    return ep, fusion, pubs


def add_overload_arguments(ap: argparse.ArgumentParser) -> None:
    """The fusion's overload settings a level passes on (:func:`overload_flags`)."""
    ap.add_argument(
        "--coalesce-max-deg",
        default=None,
        help="the fusion's --coalesce-max-deg (the overload policy's widest step, deg; 'off': "
        "batch by batch always; default: the fusion's default)",
    )
    ap.add_argument(
        "--group-budget-s",
        default=None,
        help="the fusion's --group-budget-s (the overload policy's time per pass, s)",
    )
    ap.add_argument("--bulk-max", type=int, default=None, help="the fusion's --bulk-max")
    ap.add_argument(
        "--delta-split-s",
        default=None,
        help="the fusion's --delta-split-s (a long group's delta published in parts of about "
        "this much work, s; 'off': one delta per group; default: the fusion's default)",
    )


def overload_flags(a) -> tuple[str, ...]:
    """``skyfuse fusion`` flags of the settings of :func:`add_overload_arguments` given."""
    extra: tuple[str, ...] = ()
    if a.coalesce_max_deg is not None:
        extra += ("--coalesce-max-deg", str(a.coalesce_max_deg))
    if getattr(a, "group_budget_s", None) is not None:
        extra += ("--group-budget-s", str(a.group_budget_s))
    if a.bulk_max is not None:
        extra += ("--bulk-max", str(a.bulk_max))
    if a.delta_split_s is not None:
        extra += ("--delta-split-s", str(a.delta_split_s))
    return extra


def run_level(rate: float, speed: float, a, work: Path) -> dict:
    rec, offline = make_level_files(rate, speed, a, work)
    frame = (offline["frame"]["lat0"], offline["frame"]["lon0"])
    extra = () if a.max_backlog is None else ("--max-backlog", str(a.max_backlog))
    extra += overload_flags(a)
    ep, fusion, pubs = start_children(rec, speed, offline["radars"], frame, a, work, rate, extra)
    load0 = os.getloadavg()
    # a fresh state directory per level: the fusion must not resume the picture, the
    # watermarks and the seen batches of an earlier level (or of another run of the
    # script on the same host) saved less than resume_max_age ago
    state = work / f"state-{rate:.0f}"
    with open_session(TransportConfig(listen=[ep])) as s:
        fusion.start(state_home=state)
        f = Follower(s, 0)
        assert wait_for_tokens(s, [service_alive_key("fusion")], 60.0) == [], "no fusion"
        f.pid = fusion.proc.pid
        rss0 = rss_mb(f.pid)
        t0 = start_replays(pubs, state, a.publisher_cpus)
        cpu = CpuMeter(f.pid, pubs)
        go = declare_liveliness(s, service_alive_key("bench"))
        spy = _profile(fusion, a.profile, rate, a.seconds)
        while [c for c in pubs if cpu.running(c)]:
            f.pump(0.2)
        t_sent = time.monotonic() - t0
        published = offline["batches"]
        deadline = time.monotonic() + a.drain
        while time.monotonic() < deadline and not f.caught_up(published):
            f.pump(0.2)
        t_done = time.monotonic() - t0
        cpu.stop_fusion()
        time.sleep(0.7)
        f.pump(0.1)
        go.undeclare()
        if spy is not None:
            spy.wait(timeout=60)
        fusion.terminate()
        f.inbox.close()
    res = level_result(rate, speed, offline, f, t_sent, t_done, rss0, load0)
    snap = state / "skyfuse" / "fusion-bench" / "state.npz"
    size = snap.stat().st_size if snap.exists() else None
    return {**res, **cpu.result(res["plots_applied"], t_done), "state_snapshot_bytes": size}


def level_result(rate, speed, offline, f: Follower, t_sent, t_done, rss0, load0) -> dict:
    fs = f.status["bench"]
    lat, c = fs.latency_ms, fs.counters
    applied = c.get("plots_applied", 0)
    live = applied / t_done if t_done > 0 else 0.0
    off = offline["timing"]["plots_per_s"]
    off_steps = offline["timing"].get("plots_per_s_steps")
    r1 = lambda v: None if v is None else round(v, 1)  # noqa: E731
    return {
        "target_rate": rate,
        "speed": round(speed, 3),
        "plots": offline["plots_processed"],
        "batches": offline["batches"],
        "offered_plots_per_s": round(offline["plots_processed"] / t_sent, 1),
        "send_s": round(t_sent, 2),
        "measured_s": round(t_done, 2),
        "caught_up": f.caught_up(offline["batches"]),
        "backlog_plots_end": offline["plots_processed"] - applied,
        "plots_applied": applied,
        "batches_late_applied": None if fs.late is None else fs.late.batches_late,
        "oosm_track_updates": None if fs.late is None else fs.late.track_updates_oosm,
        "sustained_plots_per_s": round(live, 1),
        "offline_plots_per_s": off,
        "live_over_offline": round(live / off, 3) if off else None,
        "offline_steps_plots_per_s": off_steps,
        "live_over_offline_steps": round(live / off_steps, 3) if off_steps else None,
        "latency_ms": {k: r1(getattr(lat, k)) for k in ("p50", "p90", "p99", "max")},
        "latency_count": lat.count,
        "cycles": c.get("cycles"),
        "groups": c.get("groups"),
        "group_parts": c.get("group_parts", 0),
        "coalesced_steps": c.get("coalesced_steps"),
        "batches_coalesced": c.get("batches_coalesced"),
        "overload": overload_summary(f.series),
        "feed_messages": dict(f.feed),
        "max_backlog_batches": f.max_backlog,
        "behind_seen": f.behind_seen,
        "rss_mb_start": r1(rss0),
        "rss_mb_max": r1(max(f.rss)) if f.rss else None,
        "rss_mb_end": r1(f.rss[-1]) if f.rss else None,
        "rss_mb_series": [r1(x) for x in f.rss[:: max(1, len(f.rss) // 40)]],
        "tracks_confirmed_end": fs.tracks_confirmed,
        "offline_confirmed_final": offline.get("confirmed_tracks_final"),
        "rejected": fs.rejected,
        "loadavg_start": [round(x, 2) for x in load0],
        "loadavg_end": [round(x, 2) for x in os.getloadavg()],
    }


def overload_summary(series) -> dict | None:
    """The fusion's overload policy over the level (Status ``overload``, when it has one):
    the share of Status reports with widened steps, the largest batches per step and the
    widest step seen, and the final figures."""
    ov = [st.overload for _, _, st in series if getattr(st, "overload", None) is not None]
    if not ov:
        return None
    return {
        "active_share": round(sum(o.active for o in ov) / len(ov), 3),
        "max_batches_per_step": round(max(o.batches_per_step for o in ov), 2),
        "widest_deg": round(max(o.widest_deg for o in ov), 1),
        "last": ov[-1].model_dump(mode="json"),
        "series_t_wait_bps_deg": [
            (
                round(t - series[0][0], 2),
                round(st.backlog.oldest_wait_s, 3),
                round(st.overload.batches_per_step, 2),
                round(st.overload.widest_deg),
            )
            for t, _, st in series
            if st.overload is not None and st.backlog is not None
        ],
    }


def _profile(fusion: Child, out: Path | None, rate: float, seconds: float):
    """py-spy on the fusion process for the sending time (collapsed stacks, ``--profile``)."""
    if out is None:
        return None
    out.mkdir(parents=True, exist_ok=True)
    cmd = ["py-spy", "record", "-p", str(fusion.proc.pid), "-f", "raw", "-r", "50", "-d"]
    cmd += [str(int(seconds)), "-o", str(out / f"fusion-{rate:.0f}.txt")]
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--rates", default="2000,5000,20000")
    ap.add_argument("--seconds", type=float, default=10.0, help="wall seconds per level")
    ap.add_argument("--targets", type=int, default=1000)
    ap.add_argument("--radars", type=int, default=6, help="regional scenario: 3 to 6 radars")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--sectors", type=int, default=16, help="regional n_sectors: batches/scan")
    ap.add_argument(
        "--traffic",
        choices=("mixed", "steady", "straight"),
        default="mixed",
        help="regional routes (mixed, steady) or straight and level flights",
    )
    ap.add_argument(
        "--scan-period", type=float, default=None,
        help="every radar's revolution, s (default: the regional radars' own, 4-12 s)",
    )  # fmt: skip
    ap.add_argument("--reorder-wait", type=float, default=0.2)
    ap.add_argument(
        "--max-backlog",
        type=float,
        default=None,
        help="the fusion's --max-backlog (stop reading when behind by this, s; default off)",
    )
    add_overload_arguments(ap)
    ap.add_argument("--drain", type=float, default=20.0, help="max s to let the fusion catch up")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--profile", type=Path, default=None, help="py-spy collapsed stacks to DIR")
    ap.add_argument("--no-offline", action="store_true", help="skip skyfuse track (soak runs)")
    ap.add_argument(
        "--publisher-cpus",
        type=parse_cpus,
        default=None,
        help="run the replay processes on these cores only, e.g. 1 (radars on other hosts: "
        "the fusion is not pre-empted by its own publishers; default: any core)",
    )
    a = ap.parse_args()
    base = sim_plot_rate(a)
    print(f"regional ({a.traffic}, period {a.scan_period or 'own'}), {a.radars} radars, "
          f"{a.targets} aircraft, {a.sectors} sectors: "
          f"{base:.0f} plots per simulated s;"
          f" {os.cpu_count()} cores, load {os.getloadavg()}", flush=True)  # fmt: skip
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for rate in (float(r) for r in a.rates.split(",")):
            r = run_level(rate, rate / base, a, Path(tmp))
            print(json.dumps(r), flush=True)
            results.append(r)
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        out = {"config": {k: str(v) for k, v in vars(a).items()}, "base_plots_per_sim_s": base}
        a.json.write_text(json.dumps({**out, "levels": results}, indent=2))


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
