"""``skyfuse inspect FILE [--json [FILE]]``: what a recording holds. For MCAP: radars and
their sites, plots per radar, scans, duration, targets, tracks, topics and metadata. For
ASTERIX (pcap or raw ``.ast``): categories, sensors (SAC/SIC) with their records by kind,
time-of-day span, distinct addresses and track numbers, and the reader's rejections. A
file that is neither is an error (exit 1) that says so."""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter, defaultdict
from pathlib import Path

from pydantic import BaseModel, Field
from rich.console import Console
from rich.table import Table
from skyfuse import schemas
from skyfuse.services.recording.mcap_io import (
    NotMcapError,
    ReadStats,
    check_mcap,
    iter_recording,
    read_metadata,
)
from skyfuse.services.runtime.config import add_json_argument, add_model_arguments, build_config


class InspectConfig(BaseModel):
    file: Path = Field(description="MCAP recording or ASTERIX file (pcap, raw) to inspect")
    json_out: str | None = Field(
        None, description="Write JSON to FILE instead of tables (--json alone or -: to stdout)"
    )


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "inspect", help="summarise an MCAP recording or an ASTERIX file", description=__doc__
    )
    add_model_arguments(p, InspectConfig, positional=("file",), skip=("json_out",))
    add_json_argument(p, "Print JSON instead of tables; --json FILE writes it to FILE")
    p.set_defaults(func=run)


def inspect_recording(path: Path) -> dict:
    """Scan a recording once and summarise it (pure data, used by tests and the CLI)."""
    check_mcap(path)
    stats = ReadStats()
    topics: dict[str, int] = defaultdict(int)
    radars: dict[str, dict] = {}
    target_ids: set[int] = set()
    track_ids: set[int] = set()
    confirmed_ids: set[int] = set()
    first = last = None
    truth_messages = 0

    def radar(rid: str) -> dict:
        return radars.setdefault(
            rid,
            {
                "radar_id": rid,
                "site": None,
                "batches": 0,
                "plots": 0,
                "scans": set(),
                "first_time": None,
                "last_time": None,
                "detections": 0,
                "clutter": 0,
            },
        )

    for rec in iter_recording(path, stats=stats):
        topics[rec.topic] += 1
        first = rec.log_time if first is None else min(first, rec.log_time)
        last = rec.log_time if last is None else max(last, rec.log_time)
        msg = rec.message
        if isinstance(msg, schemas.RadarSite):
            radar(msg.radar_id)["site"] = msg.model_dump(mode="json")
        elif isinstance(msg, schemas.PlotBatch):
            r = radar(msg.radar_id)
            r["batches"] += 1
            r["plots"] += len(msg)
            r["scans"].add(msg.scan)
            r["first_time"] = msg.time_start if r["first_time"] is None else r["first_time"]
            r["last_time"] = msg.time_end
            if msg.target_id is not None:
                n_clutter = sum(1 for t in msg.target_id if t < 0)
                r["clutter"] += n_clutter
                r["detections"] += len(msg.target_id) - n_clutter
        elif isinstance(msg, schemas.Truth):
            truth_messages += 1
            target_ids.update(msg.target_id)
        elif isinstance(msg, schemas.TrackBatch):
            for t in msg.tracks:
                track_ids.add(t.track_id)
                if t.status == schemas.TrackStatus.CONFIRMED:
                    confirmed_ids.add(t.track_id)
    radar_list = []
    for r in sorted(radars.values(), key=lambda r: r["radar_id"]):
        r["scans"] = len(r["scans"])
        radar_list.append(r)
    return {
        "file": str(path),
        "size_bytes": path.stat().st_size,
        "messages": stats.messages,
        "duration_s": (last - first) / 1e9 if first is not None else 0.0,
        "start_time_ns": first,
        "end_time_ns": last,
        "radars": radar_list,
        "plots": sum(r["plots"] for r in radar_list),
        "truth_messages": truth_messages,
        "targets": len(target_ids),
        "tracks": len(track_ids),
        "confirmed_tracks": len(confirmed_ids),
        "topics": dict(sorted(topics.items())),
        "metadata": read_metadata(path),
        "rejected": stats.rejected,
        "truncated": stats.truncated,
        "errors": stats.errors,
    }


REJECTION_HINTS = ("malformed", "_no_", "_bad_", "truncated", "unknown", "resync", "dropped")


def inspect_asterix(path: Path) -> dict:
    """Summarise a pcap or raw ASTERIX file (pure data): per sensor (category, SAC/SIC)
    the records by kind, the time-of-day span, distinct addresses and track numbers;
    CAT048 plots per radar; the reader's counts and rejections. Raises
    :class:`NotMcapError` when no ASTERIX block of a decoded category is found."""
    from skyfuse.services.asterix import AsterixStreamDecoder
    from skyfuse.services.asterix.pcap import iter_file_datagrams

    sensors: dict[str, dict] = {}

    def sink(report) -> None:
        cat = int(type(report).__name__[3:6])
        key = f"CAT{cat:03d} {report.sac}/{report.sic}"
        s = sensors.setdefault(key, {"kinds": Counter(), "tod": [], "ids": set(), "tracks": set()})
        kind = getattr(report, "message_type", None)
        s["kinds"]["reports" if kind is None else f"type {kind}"] += 1
        s["tod"].append(report.tod)
        address = getattr(report, "mode_s", None) or getattr(report, "address", None)
        if address is not None:
            s["ids"].add(address)
        if getattr(report, "track_number", None) is not None:
            s["tracks"].add(report.track_number)

    decoder = AsterixStreamDecoder(report_sink=sink, report_batches=False)
    for dgram in iter_file_datagrams(path, decoder.stats):
        decoder.feed_with_types(dgram)
    decoder.flush_with_types()
    stats = dict(decoder.stats)
    categories = {k[:6]: v for k, v in stats.items() if k[:3] == "cat" and k.endswith("_records")}
    if not categories:
        raise NotMcapError(f"no ASTERIX block of a decoded category either ({stats})")
    return {
        "file": str(path),
        "size_bytes": path.stat().st_size,
        "format": "asterix",
        "categories": categories,
        "sensors": [
            {
                "sensor": key,
                "records": dict(s["kinds"]),
                "first_tod_s": min(s["tod"]),
                "last_tod_s": max(s["tod"]),
                "addresses": len(s["ids"]),
                "track_numbers": len(s["tracks"]),
            }
            for key, s in sorted(sensors.items())
        ],
        "radars": decoder.radars,
        "rejected": {k: v for k, v in stats.items() if any(h in k for h in REJECTION_HINTS)},
        "counts": stats,
        "messages": decoder.messages[:10],
    }


def print_asterix_report(info: dict, console: Console) -> None:
    cats = ", ".join(f"{k.upper()}: {v} records" for k, v in info["categories"].items())
    console.print(f"[bold]{info['file']}[/] {info['size_bytes'] / 1e6:.2f} MB, ASTERIX ({cats})")
    t = Table(title="sensors")
    for c in ("sensor", "records", "time of day", "addresses", "track numbers"):
        t.add_column(c, justify="left" if c in ("sensor", "records") else "right")
    for s in info["sensors"]:
        span = f"{_hms(s['first_tod_s'])}-{_hms(s['last_tod_s'])}"
        kinds = ", ".join(f"{n} {k}" for k, n in s["records"].items())
        t.add_row(s["sensor"], kinds, span, str(s["addresses"]), str(s["track_numbers"]))
    if info["sensors"]:
        console.print(t)
    for rid, n in info["radars"].items():
        console.print(f"CAT048 radar {rid}: {n} plots")
    if info["rejected"]:
        console.print(f"[red]rejected or skipped[/]: {info['rejected']}")
        for msg in info["messages"][:5]:
            console.print(f"  {msg}")


def _hms(tod: float) -> str:
    h, rem = divmod(tod, 3600.0)
    return f"{int(h):02d}:{int(rem // 60):02d}:{rem % 60:06.3f}"


def print_report(info: dict, console: Console) -> None:
    console.print(
        f"[bold]{info['file']}[/] {info['size_bytes'] / 1e6:.2f} MB, {info['messages']} messages, "
        f"{info['duration_s']:.1f} s"
    )
    if info["truncated"]:
        console.print("[yellow]recording has no summary (writer killed?): read linearly[/]")
    t = Table(title="radars")
    for c in (
        "radar",
        "kind",
        "lat",
        "lon",
        "scan period s",
        "batches",
        "scans",
        "plots",
        "clutter",
    ):
        t.add_column(c, justify="right" if c not in ("radar", "kind") else "left")
    for r in info["radars"]:
        s = r["site"] or {}
        t.add_row(
            r["radar_id"],
            str(s.get("kind", "?")),
            f"{s.get('lat', float('nan')):.4f}",
            f"{s.get('lon', float('nan')):.4f}",
            str(s.get("scan_period", "?")),
            str(r["batches"]),
            str(r["scans"]),
            str(r["plots"]),
            str(r["clutter"]),
        )
    console.print(t)
    console.print(
        f"targets (truth): {info['targets']}   truth messages: {info['truth_messages']}   "
        f"tracks: {info['tracks']} ({info['confirmed_tracks']} confirmed)"
    )
    tt = Table(title="topics")
    tt.add_column("topic")
    tt.add_column("messages", justify="right")
    for topic, n in info["topics"].items():
        tt.add_row(topic, str(n))
    console.print(tt)
    for name, md in info["metadata"].items():
        console.print(f"metadata [bold]{name}[/]: " + ", ".join(f"{k}={v}" for k, v in md.items()))
    if info["rejected"]:
        console.print(f"[red]rejected messages[/]: {info['rejected']}")
        for err in info["errors"][:5]:
            console.print(f"  {err}")


def run(args: argparse.Namespace) -> int:
    cfg = build_config(InspectConfig, args)
    try:
        info = inspect_recording(cfg.file)
    except FileNotFoundError as e:
        print(f"skyfuse inspect: {e}", file=sys.stderr)
        return 1
    except NotMcapError as not_mcap:
        try:
            info = inspect_asterix(cfg.file)
        except NotMcapError as e:
            print(f"skyfuse inspect: {not_mcap}; {e}", file=sys.stderr)
            return 1
    if cfg.json_out == "-":
        json.dump(info, sys.stdout, indent=2, default=str)
        sys.stdout.write("\n")
    elif cfg.json_out is not None:
        Path(cfg.json_out).write_text(json.dumps(info, indent=2, default=str) + "\n")
    elif info.get("format") == "asterix":
        print_asterix_report(info, Console())
    else:
        print_report(info, Console())
    return 0
