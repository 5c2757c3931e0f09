"""The independent reference of ``skyfuse eval --reference``: an ADS-B (CAT021) or
multilateration (CAT010) recording read into the arrays of
:class:`~skyfuse.fusion.metrics.reference_association.ReferenceSamples`.

:func:`read_reference` reads the file with
:func:`~skyfuse.services.asterix.read_reports` (pcap or raw; the date of the first
record from ``date``) and keeps one kind of report (``kind``: ``adsb``, ``mlat``, or
``auto`` — ADS-B when the file has any, else multilateration):

* **ADS-B**: every CAT021 report; the aircraft key is the target address (I080), σ the
  one its quality indicator maps to (NACp, else NUCp; :mod:`~skyfuse.schemas
  .adsb_quality`; NaN for category 0).
* **Multilateration**: CAT010 target reports of a multilateration type (I020 TYP SSR,
  Mode S or HF multilateration) with a position and a Mode-S address (I220; others are
  counted ``no_address``: nothing identifies their aircraft). σ per axis from I500
  (√((σx² + σy²)/2)), else 5 m (the survey's field monitors scatter 2–8 m per axis).
* ``sigma_m``, when given, is the σ of every report instead (e.g. an empirical figure:
  NUCp 7's 37.8 m is a 95 % bound far above the LEBL ADS-B's actual error).
* Dropped and counted: **field monitors** (CAT010 I020 RAB = 1: fixed transponders of
  the system itself, not traffic; the LEBL MLAT has six), simulated reports (SIM = 1),
  test targets (TST = 1, already dropped by the decoder: ``cat0NN_test_target``),
  track ends without a position.

Ground/airborne per report and the placing in the evaluation frame:
:mod:`.surveillance_positions`. The frame is the evaluation's (known once the offline
runner fixed it), so :meth:`ReferenceRecording.samples` converts on demand.
"""

from __future__ import annotations

import datetime as dt
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from skyfuse.fusion.metrics.reference_association import ReferenceSamples
from skyfuse.services.asterix import cat010, cat021
from skyfuse.services.evaluation.inputs import InputError, read_report_file
from skyfuse.services.evaluation.surveillance_positions import (
    ReportPositions,
    cat010_positions,
    cat021_positions,
    ground_flags,
)

KINDS = ("auto", "adsb", "mlat")
MLAT_TYPES = frozenset({0, 1, 5})  # CAT010 I020 TYP: SSR, Mode S, HF multilateration
MLAT_SIGMA_M = 5.0


@dataclass
class ReferenceRecording:
    """A reference as read (arrays over its kept reports; positions as the reports give
    them), the reader's ``counts`` and the field monitors' addresses."""

    path: Path
    kind: str
    time_ns: np.ndarray
    key: np.ndarray
    ground: np.ndarray
    sigma: np.ndarray
    callsign: np.ndarray
    mode_3a: np.ndarray
    positions: ReportPositions
    counts: Counter = field(default_factory=Counter)
    field_monitors: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.time_ns)

    def samples(self, frame, sites: dict | None = None) -> ReferenceSamples:
        """The reports placed in ``frame`` (sites: radar id → RadarSite, for CAT010 I042 /
        I040); reports that cannot be placed are left out and counted ``no_site``."""
        x, y, ok = self.positions.in_frame(frame, sites or {})
        self.counts["no_site"] = int((~ok).sum())
        return ReferenceSamples(
            self.time_ns[ok], self.key[ok], x[ok], y[ok], self.ground[ok], self.sigma[ok],
            self.callsign[ok], self.mode_3a[ok],
        )  # fmt: skip

    def summary(self) -> dict:
        """What was read: file, kind, reports and aircraft kept, the counts."""
        return {
            "file": str(self.path),
            "kind": self.kind,
            "reports": len(self),
            "aircraft": len(np.unique(self.key)),
            "field_monitors": self.field_monitors,
            "counts": dict(self.counts),
        }


def _adsb(reports: list, counts: Counter) -> tuple[list, dict]:
    kept = []
    for r in reports:
        if r.sim:
            counts["simulated"] += 1
        else:
            kept.append(r)
    sigma = np.array([np.nan if r.sigma_pos_m is None else r.sigma_pos_m for r in kept])
    cols = {"key": [r.address for r in kept], "sigma": sigma}
    return kept, cols


def _mlat(reports: list, counts: Counter) -> tuple[list, dict, list[str]]:
    kept, monitors = [], set()
    for r in reports:
        if r.typ not in MLAT_TYPES:
            counts["not_multilateration"] += 1
        elif r.x_m is None and r.rho_m is None and r.lat is None:
            counts["no_position"] += 1
        elif r.rab:
            counts["field_monitor"] += 1
            if r.mode_s is not None:
                monitors.add(f"{r.mode_s:06X}")
        elif r.sim:
            counts["simulated"] += 1
        elif r.mode_s is None:
            counts["no_address"] += 1
        else:
            kept.append(r)
    sigma = np.array(
        [
            np.sqrt((r.sigma_x_m**2 + r.sigma_y_m**2) / 2.0)
            if r.sigma_x_m is not None and r.sigma_y_m is not None
            else MLAT_SIGMA_M
            for r in kept
        ],
        dtype=float,
    )
    return kept, {"key": [r.mode_s for r in kept], "sigma": sigma}, sorted(monitors)


def read_reference(
    path: str | Path,
    *,
    date: dt.date | str | None = None,
    kind: str = "auto",
    sigma_m: float | None = None,
) -> ReferenceRecording:
    """Read an ADS-B or multilateration recording as a reference (module docstring);
    raises :class:`~skyfuse.services.evaluation.inputs.InputError`."""
    path = Path(path)
    if kind not in KINDS:
        raise InputError(f"reference kind {kind!r}: must be one of {', '.join(KINDS)}", True)
    reports, stats = read_report_file(path, "reference file", date)
    adsb = [r for r in reports if isinstance(r, cat021.Cat021Report)]
    tgt = [r for r in reports if isinstance(r, cat010.Cat010Report)]
    if kind == "auto":
        kind = "adsb" if adsb else "mlat"
    counts = Counter({k: v for k, v in stats.items() if k.endswith("_test_target")})
    monitors: list[str] = []
    if kind == "adsb":
        kept, cols = _adsb(adsb, counts)
        pos = cat021_positions(kept)
    else:
        kept, cols, monitors = _mlat(tgt, counts)
        pos = cat010_positions(kept)
    if not kept:
        what = "ADS-B (CAT021)" if kind == "adsb" else "multilateration (CAT010, Mode-S)"
        read = ", ".join(f"{k} {v}" for k, v in stats.items()) or "nothing decoded"
        raise InputError(f"{path}: no usable {what} reports (reader: {read})")
    if sigma_m is not None:
        cols["sigma"] = np.full(len(kept), float(sigma_m))
    ok = pos.placeable
    counts["no_position"] += int((~ok).sum())
    rows = np.flatnonzero(ok)
    return ReferenceRecording(
        path=path, kind=kind,
        time_ns=np.array([r.time_ns for r in kept], np.int64)[rows],
        key=np.array(cols["key"], np.int64)[rows],
        ground=ground_flags(kept)[rows], sigma=cols["sigma"][rows],
        callsign=np.array([r.callsign for r in kept], object)[rows],
        mode_3a=np.array([-1 if r.mode_3a is None else r.mode_3a for r in kept], np.int64)[rows],
        positions=pos.take(rows), counts=counts, field_monitors=monitors,
    )  # fmt: skip
