"""Recorder throughput with no loss: a publisher sends N plot batches as fast as Zenoh's
BLOCK congestion control allows to a ``skyfuse record`` process on loopback; we time the
recording and check that every batch is in the file.

    python benchmarks/service_recorder.py [--batches 20000] [--plots 50] [--json out.json]

Prints msgs/s and plots/s with and without the Foxglove map channels (which convert every
plot to WGS-84 and encode LocationFixes)."""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

CLI = "skyfuse.services.cli"
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from skyfuse.schemas import PlotBatch, RadarKind, RadarSite, Status, keys  # noqa: E402
from skyfuse.services.recording.mcap_io import iter_recording  # noqa: E402
from skyfuse.services.runtime.transport import (  # noqa: E402
    Inbox,
    TransportConfig,
    declare_publisher,
    free_port,
    loopback_endpoint,
    open_session,
    service_alive_key,
    wait_for_tokens,
    wall_stamp,
)


def batches(n: int, plots: int, seed: int = 0) -> list[bytes]:
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        t0 = 1_767_225_600_000_000_000 + i * 250_000_000
        az = np.sort(rng.uniform(0, 0.39, plots))
        out.append(
            PlotBatch(
                radar_id="R1", scan=i // 16, seq=i, sector_start=0.0, sector_width=0.39,
                time_start=t0, time_end=t0 + 250_000_000,
                time=(t0 + (az / 0.39 * 250_000_000).astype(np.int64)).tolist(),
                range=rng.uniform(1e3, 2e5, plots).tolist(), azimuth=az.tolist(),
                altitude=rng.uniform(1e3, 1e4, plots).tolist(),
            ).to_json_bytes()
        )  # fmt: skip
    return out


def run_once(payloads: list[bytes], plots: int, foxglove: bool, tmp: Path) -> dict:
    ep = loopback_endpoint(free_port())
    out, stats = tmp / f"rec-{foxglove}.mcap", tmp / f"rec-{foxglove}.json"
    args = ["record", "--out", str(out), "--listen", ep, "--stats", str(stats)]
    args += ["--status-interval", "0.1"]
    args.append("--foxglove" if foxglove else "--no-foxglove")
    proc = subprocess.Popen(
        [sys.executable, "-m", CLI, "--log-level", "WARNING", *args],
        cwd=ROOT,
        stderr=open(tmp / f"rec-{foxglove}.log", "wb"),
    )
    site = RadarSite(radar_id="R1", lat=45.0, lon=20.0, alt=100.0, kind=RadarKind.TWO_D)
    try:
        with open_session(TransportConfig(connect=[ep])) as s:
            assert wait_for_tokens(s, [service_alive_key("recorder")], 20.0) == []
            declare_publisher(s, keys.radar_site("R1")).put(site.to_json_bytes())
            pub = declare_publisher(s, keys.radar_plots("R1"))
            inbox = Inbox()
            inbox.subscribe(s, keys.service_status("recorder"), "status")
            t0 = time.perf_counter()
            for p in payloads:
                pub.put(p, attachment=wall_stamp())
            t_pub = time.perf_counter() - t0
            # wait until the recorder has written them all (its Status counts messages)
            written, deadline = 0, time.monotonic() + 120
            while written < len(payloads) + 1 and time.monotonic() < deadline:
                item = inbox.get(0.5)
                if item is not None:
                    written = Status.from_json_bytes(item.payload).counters["messages"]
            t_written = time.perf_counter() - t0
            inbox.close()
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGUSR1)  # stacks to the log
            time.sleep(1)
            proc.kill()
            print((tmp / f"rec-{foxglove}.log").read_text()[-6000:])
            raise
    t_total = time.perf_counter() - t0  # includes draining the recorder's queue at stop
    summary = json.loads(stats.read_text())
    plot_key = keys.radar_plots("R1")
    recorded = sum(1 for r in iter_recording(out, decode=False) if r.topic == plot_key)
    n = len(payloads)
    return {
        "foxglove": foxglove,
        "batches": n,
        "plots_per_batch": plots,
        "recorded": recorded,
        "lost": n - recorded,
        "publish_s": round(t_pub, 3),
        "written_s": round(t_written, 3),
        "until_closed_s": round(t_total, 3),
        "msgs_per_s": round(n / t_written, 1),
        "plots_per_s": round(n * plots / t_written, 1),
        "mb_per_s": round(sum(map(len, payloads)) / t_written / 1e6, 2),
        "file_mb": round(out.stat().st_size / 1e6, 2),
        "recorder_messages": summary["messages"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--batches", type=int, default=20_000)
    ap.add_argument("--plots", type=int, default=50)
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args()
    payloads = batches(a.batches, a.plots)
    print(f"payload {len(payloads[0])} B per batch of {a.plots} plots; cores {os.cpu_count()}")
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for fox in (False, True):
            r = run_once(payloads, a.plots, fox, Path(tmp))
            results.append(r)
            print(json.dumps(r))
    if a.json:
        a.json.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
