"""Hostile soak: the service under sustained hostile input beside valid radars, checked for
memory growth and for any effect on the valid radars' tracks (not a test: a benchmark
script; it prints its figures and writes them as JSON).

The valid side is the one of ``benchmarks/soak.py`` (its pieces are imported): the
regional scenario simulated into an MCAP file and replayed by one ``skyfuse replay
--radars ID`` process per radar at ``--rate`` plots/s in total, one ``skyfuse fusion``
(id ``bench``), one ``skyfuse record``, one ``skyfuse tracks --json`` client. Beside it, a
fuzzer in this process publishes ``--fuzz`` messages/s, cycling through:

* garbage bytes and truncated JSON on a valid radar's plots key;
* copies of a valid radar's latest batch with ``seq`` + 10⁶ (a sequence jump), with
  times an hour ahead, and repeats of an older batch (duplicates);
* plot batches under invented radar ids without a site (a new id each time), and sites
  for invented ids (crowding: ``max_radars``);
* a valid radar's site moved by 5 km (held, never applied);
* a 200 kB junk payload, junk on the fusion's track key and on a service status key.

Figures: resident memory (VmRSS) of the fusion and of the recorder per ``--window``
(median), growth of the last window against the second (the first minute is warm-up); per
valid radar, batches published (the file's), applied, refused and lost in the fusion's
last Status and recorded once; confirmed tracks per window; what the fusion and the
recorder refused, by reason.

    python benchmarks/hostile_soak.py --duration 600 --rate 2000 --fuzz 100
    python benchmarks/hostile_soak.py --duration 60 --rate 2000 --fuzz 100 --window 15
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import random
import sys
import threading
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from service_pipeline import rss_mb, start_replays  # noqa: E402
from skyfuse.schemas import PlotBatch, RadarSite, keys  # noqa: E402
from skyfuse.services.recording.mcap_io import iter_recording  # noqa: E402
from skyfuse.services.runtime.transport import (  # noqa: E402
    Inbox,
    TransportConfig,
    declare_liveliness,
    open_session,
    service_alive_key,
)
from soak import (  # noqa: E402
    drain,
    rss_growth,
    run_in_work_dir,
    send,
    services,
    start_services,
    stop_services,
    windows,
)

HOUR_NS = 3_600_000_000_000


class Fuzzer:
    """Publishes hostile messages at ``rate`` per second (module docstring) from the valid
    radars' latest batches and sites it hears; counts what it sent by kind."""

    def __init__(self, session, rate: float, radars: list[str], seed: int = 7) -> None:
        self.session, self.rate, self.radars = session, rate, radars
        self.rng = random.Random(seed)
        self.latest: dict[str, PlotBatch] = {}
        self.older: dict[str, PlotBatch] = {}
        self.sites: dict[str, RadarSite] = {}
        self.sent: Counter[str] = Counter()
        self.stop = threading.Event()
        self.ids = itertools.count()
        self.dump: list | None = None
        """(wall ns, key, payload) of every message sent, when kept (``--keep``)."""
        self.inbox = Inbox()
        self.inbox.subscribe(session, keys.ALL_PLOTS, "plots")
        self.inbox.subscribe(session, keys.ALL_SITES, "site")

    def _listen(self) -> None:
        for item in self.inbox.drain(10_000):
            try:
                if item.tag == "plots":
                    b = PlotBatch.from_json_bytes(item.payload)
                    if b.radar_id in self.radars:
                        if b.seq % 50 == 0:
                            self.older[b.radar_id] = b
                        self.latest[b.radar_id] = b
                else:
                    s = RadarSite.from_json_bytes(item.payload)
                    if s.radar_id in self.radars:
                        self.sites[s.radar_id] = s
            except ValueError:
                continue

    def _message(self, kind: str) -> tuple[str, bytes] | None:
        rid = self.rng.choice(self.radars)
        b = self.latest.get(rid)
        n = next(self.ids)
        if kind == "garbage":
            return keys.radar_plots(rid), bytes(self.rng.getrandbits(8) for _ in range(300))
        if kind == "truncated" and b is not None:
            return keys.radar_plots(rid), b.to_json_bytes()[: self.rng.randint(1, 200)]
        if kind == "jump" and b is not None:
            jump = b.model_copy(update={"seq": b.seq + 10**6})
            return keys.radar_plots(rid), jump.to_json_bytes()
        if kind == "future" and b is not None:
            shift = {"time_start": b.time_start + HOUR_NS, "time_end": b.time_end + HOUR_NS,
                     "time": [t + HOUR_NS for t in b.time], "seq": b.seq + 1}  # fmt: skip
            return keys.radar_plots(rid), b.model_copy(update=shift).to_json_bytes()
        if kind == "repeat" and rid in self.older:
            return keys.radar_plots(rid), self.older[rid].to_json_bytes()
        if kind == "invented_plots" and b is not None:
            fake = f"fuzz{n}"
            return keys.radar_plots(fake), b.model_copy(update={"radar_id": fake}).to_json_bytes()
        if kind == "invented_site" and rid in self.sites:
            fake = f"fuzzsite{n}"
            return keys.radar_site(fake), self.sites[rid].model_copy(
                update={"radar_id": fake}
            ).to_json_bytes()
        if kind == "moved_site" and rid in self.sites:
            s = self.sites[rid]
            return keys.radar_site(rid), s.model_copy(update={"lat": s.lat + 0.045}).to_json_bytes()
        if kind == "big":
            return keys.radar_plots(rid), b"[" * 200_000
        if kind == "fake_tracks":
            return keys.fusion_tracks("bench"), b'{"fusion_id":"bench","tracks":"x"}'
        if kind == "fake_status":
            return keys.service_status("recorder"), b'{"service":1}'
        return None

    KINDS = ("garbage", "truncated", "jump", "future", "repeat", "invented_plots",
             "invented_site", "moved_site", "big", "fake_tracks", "fake_status")  # fmt: skip

    def run(self) -> None:
        t0 = time.monotonic()
        for i in itertools.count():
            if self.stop.is_set():
                return
            self._listen()
            msg = self._message(self.KINDS[i % len(self.KINDS)])
            if msg is not None:
                self.session.put(msg[0], msg[1])
                if self.dump is not None:
                    self.dump.append((time.time_ns(), msg[0], msg[1]))
                self.sent[self.KINDS[i % len(self.KINDS)]] += 1
            delay = t0 + (i + 1) / self.rate - time.monotonic()
            if delay > 0:
                self.stop.wait(delay)


def _rss_sampler(pid_of, series: list, stop: threading.Event) -> None:
    """``(monotonic time, RSS MB)`` of the process ``pid_of()`` every second."""
    while not stop.wait(1.0):
        pid = pid_of()
        r = None if pid is None else rss_mb(pid)
        if r is not None:
            series.append((time.monotonic(), r))


def _windows_of(series: list, t0: float, window: float, t_sent: float) -> list[float]:
    out = []
    for i in range(max(1, int(t_sent // window))):
        inside = [r for t, r in series if t0 + i * window <= t < t0 + (i + 1) * window]
        if inside:
            out.append(round(float(np.median(inside)), 1))
    return out


def _per_radar(rec: Path, work: Path, status) -> dict:
    published = Counter(
        r.message.radar_id for r in iter_recording(rec) if isinstance(r.message, PlotBatch)
    )
    recorded: dict[str, set] = {}
    for r in iter_recording(work / "soak.mcap"):
        if isinstance(r.message, PlotBatch) and r.message.radar_id in published:
            recorded.setdefault(r.message.radar_id, set()).add((r.message.epoch, r.message.seq))
    health = {r.radar_id: r for r in status.radars}
    return {
        rid: {
            "published": n,
            "applied": health[rid].batches if rid in health else None,
            "refused": health[rid].batches_refused if rid in health else None,
            "lost": health[rid].batches_lost if rid in health else None,
            "recorded": len(recorded.get(rid, ())),
        }
        for rid, n in sorted(published.items())
    }


def run(a, work: Path) -> dict:
    sv = services(a, work)
    rec, facts, speed, pubs, recorder = sv.rec, sv.facts, sv.speed, sv.pubs, sv.recorder
    load0 = os.getloadavg()
    rec_rss: list = []
    stop_rss = threading.Event()
    with open_session(TransportConfig(listen=[sv.ep])) as s:
        f = start_services(sv, s, work)
        sampler = threading.Thread(
            target=_rss_sampler, args=(lambda: recorder.proc.pid, rec_rss, stop_rss), daemon=True
        )
        sampler.start()
        fuzz = Fuzzer(s, a.fuzz, facts["radars"])
        fuzz.dump = [] if a.keep is not None else None
        time.sleep(1.0)
        t0 = start_replays(pubs, work / "state-home")
        go = declare_liveliness(s, service_alive_key("bench"))
        fuzzing = threading.Thread(target=fuzz.run, daemon=True)
        fuzzing.start()
        send(f, pubs)
        t_sent = time.monotonic() - t0
        fuzz.stop.set()
        fuzzing.join(5.0)
        drain(f, a.drain, lambda: not f.status["bench"].counters.get("queued", 1))
        go.undeclare()
        stop_rss.set()
        rcs = stop_services(sv)
        fuzz.inbox.close()
        f.inbox.close()
    if fuzz.dump is not None:
        import pickle

        (work / "fuzz.pickle").write_bytes(pickle.dumps(fuzz.dump))
    fs = f.status["bench"]
    ws = windows(f, t0, a.window, t_sent)
    rec_ws = _windows_of(rec_rss, t0, a.window, t_sent)
    rec_growth = (
        round(100.0 * (rec_ws[-1] - rec_ws[1]) / rec_ws[1], 2) if len(rec_ws) >= 3 else None
    )
    return {
        "config": {k: str(v) for k, v in vars(a).items()},
        "speed": round(speed, 3),
        "send_s": round(t_sent, 1),
        "offered_plots_per_s": round(facts["plots_processed"] / t_sent, 1),
        "fuzz_sent": dict(fuzz.sent),
        "fuzz_per_s": round(sum(fuzz.sent.values()) / t_sent, 1),
        "exit_codes": rcs | {c.name: c.poll() for c in pubs},
        "loadavg_start": [round(x, 2) for x in load0],
        "loadavg_end": [round(x, 2) for x in os.getloadavg()],
        "valid_radars": _per_radar(rec, work, fs),
        "fusion_rejected": fs.rejected,
        "recorder_rejected": json.loads((work / "recorder.json").read_text()).get("rejected"),
        "fusion_radars_reported": len(fs.radars),
        "windows": ws,
        "fusion_rss": rss_growth(ws),
        "recorder_rss_mb_per_window": rec_ws,
        "recorder_rss_growth_pct": rec_growth,
        "confirmed_tracks_per_window": [w["tracks_confirmed"] for w in ws],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--duration", type=float, default=600.0, help="wall seconds of publishing")
    ap.add_argument("--rate", type=float, default=2000.0, help="valid plots/s (all radars)")
    ap.add_argument("--fuzz", type=float, default=100.0, help="hostile messages/s")
    ap.add_argument("--window", type=float, default=60.0, help="s per RSS/latency window")
    ap.add_argument("--targets", type=int, default=400, help="aircraft in the air")
    ap.add_argument("--radars", type=int, default=3, help="regional scenario: 3 to 6")
    ap.add_argument("--sectors", type=int, default=16, help="sector batches per revolution")
    ap.add_argument("--traffic", choices=("steady", "mixed"), default="steady")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--reorder-wait", type=float, default=0.2)
    ap.add_argument("--drain", type=float, default=60.0, help="max s to let the fusion catch up")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--keep", type=Path, default=None, help="work directory to keep")
    a = ap.parse_args()
    a.profile = None
    a.coalesce_max_deg = a.bulk_max = a.delta_split_s = None
    path = a.json or ROOT / "benchmarks" / "results" / f"hostile-soak-{a.duration:.0f}s.json"
    print(f"hostile soak: {a.duration:.0f} s, {a.rate:.0f} valid plots/s from {a.radars} "
          f"radars, {a.fuzz:.0f} hostile messages/s; load {os.getloadavg()}",
          flush=True)  # fmt: skip
    out = run_in_work_dir(a, run)
    keep = ("valid_radars", "fuzz_sent", "fuzz_per_s", "fusion_rejected", "recorder_rejected",
            "fusion_rss", "recorder_rss_mb_per_window", "recorder_rss_growth_pct",
            "confirmed_tracks_per_window", "offered_plots_per_s", "exit_codes",
            "loadavg_end")  # fmt: skip
    print(json.dumps({k: out[k] for k in keep}, indent=1))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2))
    print(f"wrote {path}")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
