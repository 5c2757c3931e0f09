"""Soak (docs/reliability.md §6): the whole service on loopback for a long run, checked for silent
loss, memory growth and latency drift.

One ``skyfuse replay --radars ID`` publisher process per radar (the ``regional``
scenario, ``--radars`` radars, ``--targets`` aircraft; by default ``traffic = steady``, so
the number of aircraft in the air and the plot rate are stationary over the run; simulated
first into an MCAP file whose replay speed gives ``--rate`` plots/s, :func:`level`), one
``skyfuse fusion`` (id ``bench``, snapshots on, state in the run's directory), one
``skyfuse record`` and one ``skyfuse tracks --json`` client, for ``--duration`` wall
seconds. The processes and the Zenoh sessions are the ones of
``benchmarks/service_pipeline.py`` (its pieces are imported).

Checks, at the end (after the fusion drained its queue):

* **no batch missing from the recording**: recorded plot batches (distinct
  ``(radar, epoch, seq)``) = published (the simulated file's), and recorded plots =
  published plots;
* **no silent loss in the fusion**: batches received = published, and batches received
  = batches applied (``cycles``) + batch rejections counted by reason (Status
  ``rejected``, plot-level ``plot: …`` reasons apart); plots accepted = plots applied;
* **the client** received every track message the fusion published
  (``track_batches_published``) — counted from its JSON lines;
* **resident memory** of the fusion process (VmRSS at every Status): the median of the
  last ``--window`` s against the median of the second window (the first is warm-up),
  growth in %;
* **latency** (sender's sweep-end stamp → publication of the delta with the batch, the
  fusion's own measure, over every batch) p50 / p99 per window: the fusion's
  ``--latency-window`` is set to the batches of one window, so the Status at each window
  end gives the percentiles of that window.

Prints the figures and writes them as JSON (default ``benchmarks/results/soak-R-Ds.json``).

    python benchmarks/soak.py --duration 600 --rate 5000        # the 10-minute soak
    python benchmarks/soak.py --duration 60 --rate 1000 --window 15   # a quick check
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from service_pipeline import (  # noqa: E402
    Follower,
    add_overload_arguments,
    make_level_files,
    overload_flags,
    sim_plot_rate,
    start_children,
    start_replays,
)
from skyfuse.fusion.sim import build_scenario  # noqa: E402
from skyfuse.services.evaluation.demo import Child  # noqa: E402
from skyfuse.services.runtime.transport import (  # noqa: E402
    TransportConfig,
    declare_liveliness,
    open_session,
    service_alive_key,
    wait_for_tokens,
)


def observers(ep: str, work: Path) -> tuple[Child, Child]:
    """The recorder and the track client (not started)."""
    rec = Child(
        "recorder",
        ["--log-level", "WARNING", "record", "--out", str(work / "soak.mcap"), "--stats",
         str(work / "recorder.json"), "--connect", ep],
        work / "recorder.log",
    )  # fmt: skip
    client = Child(
        "tracks",
        ["--log-level", "WARNING", "tracks", "--fusion-id", "bench", "--json",
         str(work / "tracks.jsonl"), "--connect", ep],
        work / "tracks.log",
    )  # fmt: skip
    return rec, client


def level(a, work: Path) -> tuple[Path, dict, float]:
    """The soak's recording, its facts and the replay speed that gives ``--rate``.

    The speed first comes from the plot rate of a 30 s scenario with ``--targets``
    aircraft (steady traffic: nearly all of them in the air). Steady traffic: ``--targets`` is
    the number of aircraft in the air; the scenario gets ``--targets`` / f aircraft over
    its D = duration × speed simulated seconds, f being the fraction of them in the air
    at any instant (from the built routes, no simulation), and the speed is then set
    from the file's own plot count (P plots over D s: speed = rate · D / P), so the
    offered rate is ``--rate`` and the wall duration P / rate is about ``--duration``."""
    speed = a.rate / sim_plot_rate(a)
    a.seconds, a.no_offline = a.duration, True
    if a.traffic == "steady":
        a.aircraft_in_air = a.targets
        a.targets = round(a.targets / in_air_fraction(a, a.duration * speed))
    rec, facts = make_level_files(a.rate, speed, a, work)
    if a.traffic == "steady":
        speed = a.rate * a.duration * speed / facts["plots_processed"]
    return rec, facts, speed


def in_air_fraction(a, duration: float, n: int = 2000) -> float:
    """Mean fraction of the steady scenario's aircraft in the air over ``duration`` s."""
    sc = build_scenario(
        "regional", seed=a.seed, duration=duration, targets=n, radars=a.radars, traffic="steady"
    )
    birth, death = sc.targets.t_birth, sc.targets.t_death
    times = np.linspace(0.0, duration, 11)
    return float(np.mean([((birth <= t) & (death >= t)).mean() for t in times]))


def services(a, work: Path, extra: tuple = ()) -> SimpleNamespace:
    """The leveled input (:func:`level`) and the children, not started: the fusion (its
    latency window the batches of one ``--window``, its state in ``work``, then ``extra``
    flags), one replay per radar, the recorder and the track client."""
    rec, facts, speed = level(a, work)
    per_window = max(10, round(facts["batches"] / a.duration * a.window))
    frame = (facts["frame"]["lat0"], facts["frame"]["lon0"])
    flags = ("--latency-window", str(per_window), "--state-dir", str(work / "fusion-state"))
    ep, fusion, pubs = start_children(
        rec, speed, facts["radars"], frame, a, work, a.rate, fusion_extra=flags + tuple(extra)
    )
    recorder, client = observers(ep, work)
    return SimpleNamespace(rec=rec, facts=facts, speed=speed, ep=ep, fusion=fusion, pubs=pubs,
                           recorder=recorder, client=client)  # fmt: skip


def start_services(sv: SimpleNamespace, s, work: Path) -> Follower:
    """Start the fusion, the recorder and the client; wait for the first two on session
    ``s``; follow the fusion's Status."""
    for c in (sv.fusion, sv.recorder, sv.client):
        c.start(state_home=work / "state-home")
    names = [service_alive_key("fusion"), service_alive_key("recorder")]
    assert wait_for_tokens(s, names, 60.0) == [], "fusion or recorder did not start"
    return Follower(s, sv.fusion.proc.pid)


def send(f: Follower, pubs: list) -> None:
    """Follow the fusion while the replays publish."""
    while any(c.poll() is None for c in pubs):
        f.pump(0.2)


def drain(f: Follower, seconds: float, done) -> None:
    """Follow the fusion until ``done()`` or ``seconds``, then take its last Status."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and not done():
        f.pump(0.2)
    time.sleep(1.0)  # the last Status after the drain
    f.pump(0.1)


def stop_services(sv: SimpleNamespace) -> dict:
    """Stop the client, the recorder and the fusion: their exit codes."""
    return {c.name: c.terminate(timeout=15.0) for c in (sv.client, sv.recorder, sv.fusion)}


def run(a, work: Path) -> dict:
    sv = services(a, work, overload_flags(a))
    facts, speed, pubs = sv.facts, sv.speed, sv.pubs
    base = a.rate / speed
    load0 = os.getloadavg()
    with open_session(TransportConfig(listen=[sv.ep])) as s:
        f = start_services(sv, s, work)
        time.sleep(1.0)  # the client's subscription propagates
        t0 = start_replays(pubs, work / "state-home")
        go = declare_liveliness(s, service_alive_key("bench"))
        send(f, pubs)
        t_sent = time.monotonic() - t0
        drain(f, a.drain, lambda: f.caught_up(facts["batches"]))
        go.undeclare()
        rcs = stop_services(sv)
        f.inbox.close()
    out = {
        "config": {k: str(v) for k, v in vars(a).items()},
        "base_plots_per_sim_s": round(base, 1),
        "speed": round(speed, 3),
        "send_s": round(t_sent, 1),
        "offered_plots_per_s": round(facts["plots_processed"] / t_sent, 1),
        "exit_codes": rcs | {c.name: c.poll() for c in pubs},
        "loadavg_start": [round(x, 2) for x in load0],
        "loadavg_end": [round(x, 2) for x in os.getloadavg()],
    }
    out["accounting"] = accounting(facts, f, work)
    out["windows"] = windows(f, t0, a.window, t_sent)
    out["rss"] = rss_growth(out["windows"])
    return out


FUSION_COUNTERS = (
    "batches_received", "batches_in", "cycles", "plots_in", "plots_applied",
    "batches_late_applied", "track_batches_published", "state_saves", "state_published",
    "state_save_errors", "groups", "coalesced_steps", "batches_coalesced", "coalesced_retried",
)  # fmt: skip


def accounting(facts: dict, f: Follower, work: Path) -> dict:
    """published = recorded = fused + counted rejections (module docstring)."""
    from skyfuse.schemas import PlotBatch
    from skyfuse.services.recording.mcap_io import iter_recording

    ids, plots = set(), 0
    for r in iter_recording(work / "soak.mcap"):
        if isinstance(r.message, PlotBatch):
            ids.add((r.message.radar_id, r.message.epoch, r.message.seq))
            plots += len(r.message)
    fs = f.status["bench"]
    c = fs.counters
    batch_rejections = {k: n for k, n in fs.rejected.items() if not k.startswith("plot: ")}
    lines = (work / "tracks.jsonl").read_text().splitlines()
    client_tracks = sum('/tracks"' in ln[:200] for ln in lines)
    rec_stats = json.loads((work / "recorder.json").read_text())
    queued = fs.backlog.batches if fs.backlog is not None else 0
    queued_plots = fs.backlog.plots if fs.backlog is not None else 0
    checks = {
        "recorded_batches_eq_published": len(ids) == facts["batches"],
        "recorded_plots_eq_published": plots == facts["plots_processed"],
        "fusion_received_eq_published": c.get("batches_received") == facts["batches"],
        # what the fusion has not applied yet is still queued (reported), not lost
        "received_eq_applied_plus_rejected_plus_queued": c.get("batches_received")
        == c.get("cycles", 0) + sum(batch_rejections.values()) + queued,
        "plots_accepted_eq_applied_plus_queued": c.get("plots_in")
        == c.get("plots_applied", 0) + queued_plots,
        "client_got_every_track_message": client_tracks == c.get("track_batches_published"),
    }
    return {
        "published_batches": facts["batches"],
        "published_plots": facts["plots_processed"],
        "recorded_batches": len(ids),
        "recorded_plots": plots,
        "recorder_rejected": rec_stats.get("rejected", {}),
        "fusion_counters": {k: c.get(k) for k in FUSION_COUNTERS},
        "fusion_rejected": fs.rejected,
        "fusion_queued_at_end": {"batches": queued, "plots": queued_plots},
        "fusion_late": fs.late.model_dump() if fs.late is not None else None,
        "client_track_messages": client_tracks,
        "tracks_confirmed_end": fs.tracks_confirmed,
        "checks": checks,
        "all_ok": all(checks.values()),
    }


def windows(f: Follower, t0: float, window: float, t_sent: float) -> list[dict]:
    """Per window of the sending time: the fusion's latency percentiles at its end (over
    that window's batches), the median RSS and the largest backlog inside it."""
    out = []
    n = max(1, int(t_sent // window))
    for i in range(n):
        lo, hi = t0 + i * window, t0 + (i + 1) * window
        inside = [(t, r, st) for t, r, st in f.series if lo <= t < hi]
        if not inside:
            continue
        last = inside[-1][2]
        rss = [r for _, r, _ in inside if r is not None]
        lat = last.latency_ms
        out.append({
            "t_s": round((i + 1) * window, 1),
            "latency_p50_ms": None if lat.p50 is None else round(lat.p50, 1),
            "latency_p99_ms": None if lat.p99 is None else round(lat.p99, 1),
            "latency_count": lat.count,
            "rss_mb_median": round(float(np.median(rss)), 1) if rss else None,
            "max_backlog_batches": max(st.backlog.batches for _, _, st in inside if st.backlog),
            "behind": any(st.backlog.behind for _, _, st in inside if st.backlog),
            "tracks_confirmed": last.tracks_confirmed,
        })  # fmt: skip
    return out


def rss_growth(ws: list[dict]) -> dict:
    """RSS of the last window against the second one (the first is warm-up), %."""
    vals = [w["rss_mb_median"] for w in ws if w["rss_mb_median"] is not None]
    if len(vals) < 3:
        return {"growth_pct": None, "note": "fewer than 3 windows"}
    ref, end = vals[1], vals[-1]
    return {"reference_mb": ref, "end_mb": end, "max_mb": max(vals),
            "growth_pct": round(100.0 * (end - ref) / ref, 2)}  # fmt: skip


def run_in_work_dir(a, run) -> dict:
    """``run(a, work)`` in ``--keep`` (kept: the simulated file, the recording, logs and
    state) or in a temporary directory; prints the result's windows, one JSON line each."""
    if a.keep is not None:
        a.keep.mkdir(parents=True, exist_ok=True)
        out = run(a, a.keep)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            out = run(a, Path(tmp))
    for w in out["windows"]:
        print(json.dumps(w))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--duration", type=float, default=600.0, help="wall seconds of publishing")
    ap.add_argument("--rate", type=float, default=5000.0, help="plots/s offered (all radars)")
    ap.add_argument("--window", type=float, default=60.0, help="s per latency/RSS window")
    ap.add_argument(
        "--targets",
        type=int,
        default=1000,
        help="aircraft: in the air at any time (steady), in the scenario (mixed)",
    )
    ap.add_argument("--radars", type=int, default=4, help="regional scenario: 3 to 6")
    ap.add_argument(
        "--sectors", type=int, default=16, help="regional n_sectors: batches per revolution"
    )
    ap.add_argument(
        "--traffic",
        choices=("steady", "mixed"),
        default="steady",
        help="regional traffic: steady (stationary number of aircraft; default) or mixed",
    )
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--reorder-wait", type=float, default=0.2)
    ap.add_argument("--drain", type=float, default=60.0, help="max s to let the fusion catch up")
    add_overload_arguments(ap)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument(
        "--keep", type=Path, default=None,
        help="work directory to keep (input file, recording, client lines, logs, state)",
    )  # fmt: skip
    a = ap.parse_args()
    a.profile = None
    path = a.json or ROOT / "benchmarks" / "results" / f"soak-{a.rate:.0f}-{a.duration:.0f}s.json"
    print(
        f"soak: {a.duration:.0f} s at {a.rate:.0f} plots/s, {a.radars} radars, {a.targets} "
        f"aircraft, {a.sectors} sectors, {a.traffic} traffic; {os.cpu_count()} cores, "
        f"load {os.getloadavg()}",
        flush=True,
    )
    out = run_in_work_dir(a, run)
    print(json.dumps({k: out[k] for k in ("accounting", "rss", "offered_plots_per_s", "send_s",
                                          "exit_codes", "loadavg_end")}, indent=1))  # fmt: skip
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2))
    print(f"wrote {path}; all checks {'passed' if out['accounting']['all_ok'] else 'FAILED'}")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
