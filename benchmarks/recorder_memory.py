"""Where the recorder's memory goes over a long recording (not a test: a measurement).

The skyfuse messages of a recording (plots, sites, track feed, Status: what a ``skyfuse
record`` of a soak received) are fed to a :class:`~skyfuse.services.recording.recorder.
Recorder` in this process, ``--passes`` times over: each pass shifts the plot batches'
``seq``, ``scan`` and times and the track feed's ``cycle`` and time past the previous
pass, so every pass is new data (no duplicate refusals) and the recording gets as long as
``--passes`` soaks. Chunks are closed every ``--flush-every`` messages (the recorder
closes one every ``flush_interval`` s of wall time; fed faster than real time, the
count of messages per chunk is what matters).

After each pass: the resident memory (VmRSS), the Python heap traced by ``tracemalloc``
and its growth since the end of the first pass, by allocation site (the top
``--top`` lines, file:line); the file size and the chunks written.

    python benchmarks/recorder_memory.py SOAK.mcap --passes 6
    python benchmarks/recorder_memory.py SOAK.mcap --passes 6 --rotate-s 60 --json out.json
    python benchmarks/recorder_memory.py SOAK.mcap --passes 6 --keep-chunk-indexes \
        --foxglove-track-period 0       # the recorder as it was: the before of a comparison
"""

from __future__ import annotations

import argparse
import ctypes
import ctypes.util
import json
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from service_pipeline import rss_mb  # noqa: E402
from skyfuse.schemas import PlotBatch, TrackBatch  # noqa: E402
from skyfuse.services.recording import mcap_io  # noqa: E402
from skyfuse.services.recording.mcap_io import iter_recording  # noqa: E402
from skyfuse.services.recording.recorder import Recorder, RecorderConfig  # noqa: E402
from skyfuse.services.runtime.transport import Received  # noqa: E402


def load(path: Path, seconds: float | None) -> list[tuple[str, bytes, int]]:
    """``(key, payload, log_time)`` of the recording's skyfuse messages (Foxglove channels
    left out: the recorder makes them), of its first ``seconds`` of plots if given."""
    out: list = []
    t0 = None
    for r in iter_recording(path, decode=False):
        if t0 is None and "/plots" in r.topic:
            t0 = r.log_time
        if seconds is not None and t0 is not None and r.log_time - t0 > seconds * 1e9:
            break
        if not r.topic.startswith("/"):
            out.append((r.topic, r.data, r.log_time))
    return out


def shifted(msgs: list, k: int, span_ns: int, seq_span: dict, cycle_span: int):
    """Pass ``k`` of the messages: plots and tracks moved past pass ``k - 1``."""
    for key, payload, t in msgs:
        if k and "/plots" in key:
            try:
                b = PlotBatch.from_json_bytes(payload)
            except ValueError:
                yield key, payload, t + k * span_ns
                continue
            d = k * span_ns
            payload = b.model_copy(update={
                "seq": b.seq + k * seq_span.get(b.radar_id, 0), "scan": b.scan + k * 10**6,
                "time_start": b.time_start + d, "time_end": b.time_end + d,
                "time": [x + d for x in b.time]}).to_json_bytes()  # fmt: skip
        elif k and key.endswith("/tracks"):
            try:
                b = TrackBatch.from_json_bytes(payload)
            except ValueError:
                yield key, payload, t + k * span_ns
                continue
            payload = b.model_copy(
                update={"cycle": b.cycle + k * cycle_span, "time": b.time + k * span_ns}
            ).to_json_bytes()
        yield key, payload, t + k * span_ns


def spans(msgs: list) -> tuple[int, dict, int]:
    """The recording's time span (ns), per radar its seq span, the track cycles' span."""
    t = [m[2] for m in msgs]
    seqs: dict[str, int] = {}
    cycles = 0
    for key, payload, _ in msgs:
        if "/plots" in key:
            try:
                b = PlotBatch.from_json_bytes(payload)
            except ValueError:
                continue
            seqs[b.radar_id] = max(seqs.get(b.radar_id, 0), b.seq + 1)
        elif key.endswith("/tracks"):
            try:
                cycles = max(cycles, TrackBatch.from_json_bytes(payload).cycle + 1)
            except ValueError:
                continue
    return max(t) - min(t) + 1_000_000_000, seqs, cycles


def top_growth(before, after, n: int) -> list[dict]:
    stats = after.compare_to(before, "lineno")
    out = []
    for s in stats[:n]:
        frame = s.traceback[0]
        out.append({"site": f"{Path(frame.filename).name}:{frame.lineno}",
                    "path": frame.filename, "kb": round(s.size_diff / 1024, 1),
                    "count": s.count_diff})  # fmt: skip
    return out


class _Mallinfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in ("arena", "ordblks", "smblks", "hblks",
                "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks", "keepcost")]  # fmt: skip


_LIBC = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
_LIBC.mallinfo2.restype = _Mallinfo2


def malloc_mb() -> dict:
    """glibc's heap, all arenas (``mallinfo2``): in use by malloc's callers, free but
    held by malloc (not returned to the system), mmapped blocks; MB."""
    m = _LIBC.mallinfo2()
    mb = 1 / 2**20
    return {"in_use": round(m.uordblks * mb, 1), "free_held": round(m.fordblks * mb, 1),
            "mmapped": round(m.hblkhd * mb, 1)}  # fmt: skip


def _pass_row(a, rec, k: int, n: int, t0: float) -> dict:
    row = {"pass": k, "messages": n, "s": round(time.perf_counter() - t0, 1),
           "rss_mb": rss_mb("self"), "malloc_mb": malloc_mb(),
           "file_mb": round(sum(p.stat().st_size for p in rec.files) / 1e6, 1),
           "files": len(rec.files)}  # fmt: skip
    if tracemalloc.is_tracing():
        row["traced_mb"] = round(tracemalloc.get_traced_memory()[0] / 2**20, 2)
    if a.trim:
        _LIBC.malloc_trim(0)
        row["rss_mb_after_malloc_trim"] = rss_mb("self")
    return row


def run(a, work: Path) -> dict:
    msgs = load(a.recording, a.seconds)
    span_ns, seq_span, cycle_span = spans(msgs)
    print(f"{len(msgs)} messages over {span_ns / 1e9:.0f} s", flush=True)
    cfg = RecorderConfig(out=work / "mem.mcap", foxglove=not a.no_foxglove,
                         flush_interval=60, rotate_s=a.rotate_s, rotate_mb=a.rotate_mb,
                         foxglove_track_period=a.foxglove_track_period)  # fmt: skip
    if a.keep_chunk_indexes:  # mcap's Writer keeps its list of them (no spill)
        mcap_io.spill_chunk_indexes = lambda writer, directory=None: None
    if a.frames:
        tracemalloc.start(a.frames)
    rec = Recorder(cfg)
    passes, first = [], None
    n = 0
    for k in range(a.passes):
        t0 = time.perf_counter()
        for key, payload, t in shifted(msgs, k, span_ns, seq_span, cycle_span):
            rec.handle(Received("data", key, payload, True, t, t))
            n += 1
            if n % a.flush_every == 0:
                rec.maybe_flush(now=time.monotonic() + 1e9)  # close the chunk now
                rec._last_flush = time.monotonic()
        row = _pass_row(a, rec, k, n, t0)
        if tracemalloc.is_tracing():
            snap = tracemalloc.take_snapshot().filter_traces(
                [tracemalloc.Filter(False, tracemalloc.__file__)]
            )
            if first is None:
                first = snap
            else:
                row["growth_since_pass_0"] = top_growth(first, snap, a.top)
        passes.append(row)
        print(json.dumps({k: v for k, v in row.items() if k != "growth_since_pass_0"}),
              flush=True)  # fmt: skip
    rec.close()
    return {"config": {k: str(v) for k, v in vars(a).items()}, "passes": passes}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("recording", type=Path, help="an MCAP recording (e.g. a soak's)")
    ap.add_argument("--passes", type=int, default=6)
    ap.add_argument("--seconds", type=float, default=None, help="of the recording, per pass")
    ap.add_argument("--flush-every", type=int, default=150, help="messages per chunk")
    ap.add_argument("--rotate-s", type=float, default=None)
    ap.add_argument("--rotate-mb", type=float, default=None)
    ap.add_argument("--no-foxglove", action="store_true")
    ap.add_argument("--foxglove-track-period", type=float, default=1.0)
    ap.add_argument(
        "--keep-chunk-indexes",
        action="store_true",
        help="leave the chunk indexes in the writer's memory (no spill)",
    )
    ap.add_argument("--frames", type=int, default=1, help="tracemalloc depth (0: off)")
    ap.add_argument("--trim", action="store_true", help="malloc_trim(0) after each pass")
    ap.add_argument("--top", type=int, default=12)
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = run(a, Path(tmp))
    last = out["passes"][-1].get("growth_since_pass_0", [])
    print("growth since the end of pass 0, by allocation site:")
    for g in last:
        print(f"  {g['kb']:>10.1f} KiB {g['count']:>8} blocks  {g['site']}  ({g['path']})")
    if a.json:
        a.json.write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
