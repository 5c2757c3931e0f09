"""Sustained plots/s and latency through sensor → fusion → feed, as separate processes
over Zenoh on loopback (3 simulated radars of the regional scenario, the fusion service,
and this process as the feed subscriber).

For each offered rate R (plots/s) the scenario is run at the speed that makes its plot
rate R; the script reports the rate offered by the sensors, the rate the fusion service
sustained (plots applied / time until it caught up, or until the ``--drain`` limit
after the sensors finished: then the backlog is reported), the latency from the sensor's
sweep end to the TrackBatch publication (fusion Status percentiles; it includes the
reorder wait), and the TrackBatches the feed received.

    python benchmarks/service_pipeline.py [--rates 1000,5000,20000] [--seconds 15]
        [--targets 150] [--reorder-wait 0.1] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from skyfuse.fusion.sim import Simulator, build_scenario  # noqa: E402
from skyfuse.schemas import Status, keys  # noqa: E402
from skyfuse.services.evaluation.demo import Child  # noqa: E402
from skyfuse.services.runtime.transport import (  # noqa: E402
    Inbox,
    TransportConfig,
    declare_liveliness,
    loopback_endpoint,
    open_session,
    service_alive_key,
    wait_for_tokens,
)

RADARS = 3


def sim_plot_rate(targets: int, seed: int, duration: float = 60.0) -> float:
    """Plots per simulated second of the scenario (all radars)."""
    sc = build_scenario("regional", seed=seed, duration=duration, targets=targets, radars=RADARS)
    n = sum(len(ev.message.time) for ev in Simulator(sc, seed=seed).run() if ev.kind == "plots")
    return n / duration


def run_level(rate: float, speed: float, a, work: Path) -> dict:
    sc_duration = a.seconds * speed
    sc = build_scenario(
        "regional", seed=a.seed, duration=sc_duration, targets=a.targets, radars=RADARS
    )
    f = sc.frame
    ep = loopback_endpoint()
    common = ["--connect", ep]
    scen = [
        "--scenario", "regional", "--seed", str(a.seed), "--duration", str(sc_duration),
        "--targets", str(a.targets), "--param", f"radars={RADARS}",
    ]  # fmt: skip
    fusion = Child(
        "fusion",
        [
            "--log-level", "WARNING", "fusion", "--fusion-id", "bench", "--reorder-wait",
            str(a.reorder_wait), "--frame-lat0", repr(f.lat0), "--frame-lon0", repr(f.lon0),
            "--status-interval", "0.5", "--latency-window", "1000000", *common,
        ],
        work / f"fusion-{rate:.0f}.log",
    )  # fmt: skip
    sensors = [
        Child(
            f"sensor-{s.radar_id}",
            [
                "--log-level",
                "WARNING",
                "sensor",
                "--radar",
                s.radar_id,
                *scen,
                "--speed",
                f"{speed:.4f}",
                "--wait-for",
                "bench",
                "--status-interval",
                "1",
                *common,
            ],
            work / f"sensor-{s.radar_id}-{rate:.0f}.log",
        )
        for s in sc.sites
    ]
    status: dict[str, Status] = {}
    track_batches = 0
    with open_session(TransportConfig(listen=[ep])) as s:
        inbox = Inbox()
        inbox.subscribe(s, f"{keys.PREFIX}/fusion/bench/*", "fusion")
        inbox.subscribe(s, f"{keys.PREFIX}/service/*/status", "status")
        fusion.start()
        for c in sensors:
            c.start()
        ready = [service_alive_key("fusion")] + [service_alive_key(c.name) for c in sensors]
        assert wait_for_tokens(s, ready, 60.0) == [], "services did not start"
        go = declare_liveliness(s, service_alive_key("bench"))
        spy = _profile(fusion, a.profile, rate)
        t0 = time.monotonic()
        last_fusion_status = [0.0]

        def pump(timeout: float) -> None:
            nonlocal track_batches
            item = inbox.get(timeout)
            while item is not None:
                if item.key.endswith("/tracks"):
                    track_batches += 1
                elif item.key.endswith("/status"):
                    st = Status.from_json_bytes(item.payload)
                    status[st.service_id] = st
                    if st.service_id == "bench":
                        last_fusion_status[0] = time.monotonic() - t0
                item = inbox.get(0) if inbox.qsize() else None

        while any(c.poll() is None for c in sensors):
            pump(0.2)
        t_sent = time.monotonic() - t0
        published = sum(status[c.name].counters["batches"] for c in sensors if c.name in status)
        plots_sent = sum(status[c.name].counters["plots"] for c in sensors if c.name in status)
        deadline = time.monotonic() + a.drain
        while time.monotonic() < deadline:
            pump(0.2)
            fs = status.get("bench")
            if fs and fs.counters.get("batches_received", 0) >= published:
                if fs.counters.get("queued", 0) == 0:
                    break
        time.sleep(0.7)
        pump(0.1)
        fs = status["bench"]
        t_done = last_fusion_status[0]
        go.undeclare()
        if spy is not None:
            spy.wait(timeout=60)
        fusion.terminate()
        inbox.close()
    lat = fs.latency_ms
    return {
        "offered_plots_per_s": round(plots_sent / t_sent, 1),
        "target_rate": rate,
        "speed": round(speed, 3),
        "batches_sent": published,
        "plots_sent": plots_sent,
        "send_s": round(t_sent, 2),
        "measured_s": round(t_done, 2),
        "caught_up": fs.counters.get("batches_received", 0) >= published
        and fs.counters.get("queued", 0) == 0,
        "backlog_plots": plots_sent - fs.counters.get("plots_applied", 0),
        "fusion_plots_in": fs.counters.get("plots_in"),
        "fusion_cycles": fs.counters.get("cycles"),
        "fusion_plots_applied": fs.counters.get("plots_applied"),
        "sustained_plots_per_s": round(fs.counters.get("plots_applied", 0) / t_done, 1),
        "feed_track_batches": track_batches,
        "latency_ms_p50": round(lat.p50, 1) if lat and lat.p50 is not None else None,
        "latency_ms_p99": round(lat.p99, 1) if lat and lat.p99 is not None else None,
        "rejected": fs.rejected,
        "tracks_confirmed_end": fs.tracks_confirmed,
    }


def _profile(fusion: Child, out: Path | None, rate: float):
    """py-spy on the fusion process for the sending time (collapsed stacks, ``--profile``)."""
    if out is None:
        return None
    import subprocess

    out.mkdir(parents=True, exist_ok=True)
    cmd = ["py-spy", "record", "-p", str(fusion.proc.pid), "-f", "raw", "-r", "50", "-d"]
    cmd += [str(int(out_seconds[0])), "-o", str(out / f"fusion-{rate:.0f}.txt")]
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


out_seconds = [15.0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--rates", default="1000,5000,20000")
    ap.add_argument("--seconds", type=float, default=15.0, help="wall seconds per level")
    ap.add_argument("--targets", type=int, default=150)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--reorder-wait", type=float, default=0.1)
    ap.add_argument("--drain", type=float, default=20.0, help="max s to let the fusion catch up")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--profile", type=Path, default=None, help="py-spy collapsed stacks to DIR")
    a = ap.parse_args()
    out_seconds[0] = a.seconds
    base = sim_plot_rate(a.targets, a.seed)
    print(f"regional, {RADARS} radars, {a.targets} aircraft: {base:.0f} plots per simulated s;"
          f" {os.cpu_count()} cores", flush=True)  # fmt: skip
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for rate in (float(r) for r in a.rates.split(",")):
            r = run_level(rate, rate / base, a, Path(tmp))
            print(json.dumps(r), flush=True)
            results.append(r)
    if a.json:
        a.json.write_text(json.dumps({"base_plots_per_sim_s": base, "levels": results}, indent=2))


if __name__ == "__main__":
    main()
