"""When each report-based sensor last reported each track: the detection semantics of
sensors that report the targets they track (ADS-B, multilateration) instead of sweeping a
coverage.

A radar looks at every target in its coverage each scan, so a track it did not detect is
a missed detection (P_D applies, [thesis] 2.39-2.41). A report-based sensor's silence
about a track means a miss only if that sensor reports this target at all: an aircraft
without ADS-B, a vehicle without a transponder, is never reported by ADS-B or
multilateration, and that is no evidence against its existence. So a report-based sensor's
P_D applies to a track only while the sensor has reported it within ``report_timeout``
seconds (:meth:`ReportClock.recent`): a cooperative track whose reports stop is eroded by
that sensor's misses for that long (then the sensor falls silent about it: an aircraft
that landed and switched its transponder off is left to the sensors that still see it),
and a non-cooperative track never is.

The clock is one column group of the track store, ``report_t`` (n, K) int64 ns: the time of
each track's last plot from each of K report-based sensors (slot k ↔ ``names[k]``, given
in the order the sensors first report; 0 = never). K is ``TrackerConfig.report_sensors``.
"""

from __future__ import annotations

import numpy as np
from skyfuse.schemas.snapshot import SnapshotError, mapping, strings

from .store import Column, ColumnGroup

NS = 1e-9


class ReportClock:
    """The report clock of one tracker (module docstring): declares ``report_t`` in the
    track store ``tracks`` with ``slots`` sensor slots."""

    def __init__(self, tracks, slots: int) -> None:
        self.tracks = tracks
        self.slots = int(slots)
        self.names: list[str] = []
        col = Column("report_t", np.int64, (self.slots,), fill=0,
                     doc="last plot of each report-based sensor, ns (0 never)")  # fmt: skip
        tracks.declare(ColumnGroup("report clock", (col,)))

    def slot(self, sensor: str) -> int:
        """The slot of ``sensor`` (a new one at its first use); ValueError beyond K."""
        if sensor not in self.names:
            if len(self.names) >= self.slots:
                raise ValueError(
                    f"sensor {sensor!r}: at most {self.slots} report-based sensors per tracker "
                    "(TrackerConfig.report_sensors)"
                )
            self.names.append(sensor)
        return self.names.index(sensor)

    def recent(self, rows: np.ndarray, sensor: str, t_ns: int, timeout: float) -> np.ndarray:
        """(len(rows),) float: 1 where ``sensor`` reported the track within ``timeout``
        seconds before ``t_ns``, else 0 (the factor of its P_D)."""
        k = self.slot(sensor)
        last = self.tracks.report_t[rows, k]
        age = (int(t_ns) - last) * NS
        return ((last > 0) & (age <= timeout)).astype(np.float64)

    def record(self, rows: np.ndarray, sensor: str, t_ns: np.ndarray) -> None:
        """The tracks ``rows`` were reported by ``sensor`` at ``t_ns`` (len(rows),) ns (a
        later report never moves back)."""
        if len(rows) == 0:
            return
        k = self.slot(sensor)
        col = self.tracks.report_t
        col[rows, k] = np.maximum(col[rows, k], np.asarray(t_ns, dtype=np.int64))

    def to_snapshot(self) -> dict:
        return {"names": list(self.names)}

    def from_snapshot(self, snap) -> None:
        names = strings(mapping(snap, "report clock"), "names")
        if len(names) > self.slots:
            raise SnapshotError(f"report clock: {len(names)} sensors for {self.slots} slots")
        self.names = list(names)
