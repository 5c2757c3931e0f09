"""Recordings as input of the offline runner: MCAP or ASTERIX (CAT048/CAT034 and
CAT010/CAT020/CAT021 in a pcap of UDP, or a raw ``.ast`` stream), told apart by the first
bytes; several ASTERIX recordings of different sensors merged in time order.

:func:`open_input` checks the file and says what is wrong with it (missing, not a
recording, no radar sites) with an :class:`InputError`; the result gives the messages to
:func:`~skyfuse.services.evaluation.offline.run_offline` in time order.

* MCAP: a first pass reads the topics undecoded (radar sites, number of plot batches,
  for the progress bar); the second pass decodes the messages. The sites are *not*
  passed up front: the runner learns them in recording order like the live service.
* ASTERIX: :func:`skyfuse.services.asterix.read_asterix` with the sites file (``[[radar]]``
  sac, sic, lat, lon, alt) or the CAT034 I120 positions, and the UTC date of the first
  record (default: the pcap capture time, else today). Several files (e.g. a surface
  movement radar's and a multilateration system's recordings of the same period) are
  each read so, then merged (:func:`~skyfuse.services.asterix.merge_results`: batches in
  ``(time_end, sensor id, seq)`` order); a sensor in two files is an error.
"""

from __future__ import annotations

import datetime as dt
import logging
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from skyfuse.schemas import RadarSite, keys
from skyfuse.services.recording.mcap_io import MCAP_MAGIC, ReadStats, iter_recording

log = logging.getLogger(__name__)


class InputError(ValueError):
    """The input file cannot be run: the message says which file and why. ``usage``:
    the command line is at fault (missing file, unusable sites file: exit code 2), else
    the file's content (exit code 1)."""

    def __init__(self, message: str, usage: bool = False) -> None:
        super().__init__(message)
        self.usage = usage


def is_mcap(path: Path) -> bool:
    """True when the file starts with the MCAP magic (else: ASTERIX pcap or raw)."""
    with open(path, "rb") as f:
        return f.read(5) == MCAP_MAGIC[:5]


@dataclass
class RecordingInput:
    """An opened input: ``messages()`` iterates it in time order; ``sites`` are the
    sites known up front (ASTERIX), ``sites_in_file`` all sites the file names;
    ``n_batches`` plot batches; ``asterix`` the reader's result for ASTERIX input."""

    path: Path
    sites: dict[str, RadarSite]
    sites_in_file: dict[str, RadarSite]
    n_batches: int
    asterix: object | None = None
    stats: ReadStats = field(default_factory=ReadStats)

    def messages(self) -> Iterator:
        if self.asterix is not None:
            return iter(self.asterix.batches)
        return (rec.message for rec in iter_recording(self.path, stats=self.stats))


def scan_recording(path: Path) -> tuple[dict[str, RadarSite], int]:
    """First pass over an MCAP recording: the radar sites and the number of plot batches."""
    sites: dict[str, RadarSite] = {}
    n_batches = 0
    for rec in iter_recording(path, decode=False):
        if rec.topic.startswith(keys.PREFIX + "/radar/"):
            if rec.topic.endswith("/site"):
                try:
                    site = RadarSite.from_json_bytes(rec.data)
                except ValueError as e:
                    log.warning("skipping invalid site on %s: %s", rec.topic, e)
                    continue
                sites.setdefault(site.radar_id, site)
            elif rec.topic.endswith("/plots"):
                n_batches += 1
    return sites, n_batches


def parse_date(date: dt.date | str | None) -> dt.date | None:
    """A UTC date given as ``datetime.date`` or ``"YYYY-MM-DD"`` (InputError otherwise)."""
    if isinstance(date, str):
        try:
            return dt.date.fromisoformat(date)
        except ValueError:
            raise InputError(f"date {date!r} is not YYYY-MM-DD", usage=True) from None
    return date


def read_report_file(path: Path, what: str, date: dt.date | str | None = None):
    """The CAT010/CAT020/CAT021 reports of the recording ``path`` and the decoder's
    counts (:func:`services.asterix.read_reports`), ``what`` naming the file in the
    :class:`InputError` when it is missing or cannot be read."""
    from skyfuse.services.asterix import read_reports

    if not path.is_file():
        raise InputError(f"{what}: {str(path)!r} does not exist", usage=True)
    try:
        reports, stats, _ = read_reports(path, date=parse_date(date))
    except ValueError as e:
        raise InputError(f"{path}: {e}") from None
    return reports, stats


def _open_asterix(
    paths: list[Path], sites_file, date, sector_count: int, report_window: float = 1.0,
    adsb_sigma: float | None = None,
) -> RecordingInput:  # fmt: skip
    from skyfuse.services.asterix import SitesError, load_sites, merge_results, read_asterix

    date = parse_date(date)
    sites = None
    if isinstance(sites_file, dict):
        sites_file, sites = None, sites_file
    try:
        sites = load_sites(sites_file) if sites_file is not None else sites
    except (SitesError, OSError) as e:
        raise InputError(str(e), usage=True) from None
    results = []
    for path in paths:
        res = read_asterix(path, date=date, sites=sites, sector_count=sector_count,
                           report_window=report_window, adsb_sigma=adsb_sigma)  # fmt: skip
        if not res.radars and not res.batches:
            with open(path, "rb") as f:
                head = f.read(8)
            raise InputError(
                f"{path}: not a recording: neither MCAP (magic {MCAP_MAGIC!r}) nor a pcap or "
                f"raw stream with ASTERIX CAT048/CAT034 or CAT010/020/021 records (first bytes "
                f"{head!r}; reader: "
                f"{', '.join(f'{k} {v}' for k, v in res.stats.items()) or 'nothing decoded'})"
            )
        results.append(res)
    try:
        res = results[0] if len(results) == 1 else merge_results(results, [p.name for p in paths])
    except ValueError as e:
        raise InputError(f"{', '.join(map(str, paths))}: {e}", usage=True) from None
    path = paths[0]
    for text in res.messages[:10]:
        log.info("asterix: %s", text)
    if not res.sites:
        raise InputError(
            f"{path}: no radar has a site (radars: {', '.join(res.radars) or 'none'}): give "
            "--sites with their positions"
        )
    return RecordingInput(path, dict(res.sites), dict(res.sites), len(res.batches), res)


def open_input(
    path: Path | list[Path],
    *,
    sites_file: Path | dict[str, RadarSite] | None = None,
    date: dt.date | str | None = None,
    sector_count: int = 16,
    report_window: float = 1.0,
    adsb_sigma: float | None = None,
) -> RecordingInput:
    """Open ``path`` (MCAP or ASTERIX, see the module docstring; a list: several ASTERIX
    recordings merged) or raise InputError. ASTERIX only: ``sites_file`` a sites TOML or
    ``{radar id: RadarSite}``, ``date`` a ``datetime.date`` or ``"YYYY-MM-DD"``,
    ``sector_count`` sectors per turn of radars without CAT034, ``report_window`` s the
    batch window of report sensors without cycle messages (ADS-B), ``adsb_sigma`` m an
    empirical σ of every ADS-B report (default: its NACp/NUCp)."""
    paths = [Path(p) for p in path] if isinstance(path, (list, tuple)) else [Path(path)]
    if not paths:
        raise InputError("no input file given", usage=True)
    for p in paths:
        if not p.is_file():
            what = "does not exist" if not p.exists() else "is not a file"
            raise InputError(f"file: {str(p)!r} {what}", usage=True)
    path = paths[0]
    if len(paths) > 1 and any(is_mcap(p) for p in paths):
        raise InputError(
            f"{', '.join(map(str, paths))}: several files are merged only when all are ASTERIX "
            "recordings (an MCAP recording already holds every sensor)",
            usage=True,
        )
    if not is_mcap(path):
        return _open_asterix(paths, sites_file, date, sector_count, report_window, adsb_sigma)
    for name, v in (("sites", sites_file), ("date", date)):
        if v is not None:
            log.warning("--%s applies to ASTERIX input only: ignored for MCAP", name)
    sites, n_batches = scan_recording(path)
    if not sites:
        raise InputError(f"{path}: no radar site messages: cannot convert plots")
    return RecordingInput(path, {}, sites, n_batches)
