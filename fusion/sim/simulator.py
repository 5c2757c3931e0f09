"""``Simulator``: runs a :class:`~fusion.sim.Scenario` into sector plot batches, sites and
truth, deterministically from a seed.

Two views of the same numbers:

* :meth:`Simulator.scans` — per-scan NumPy arrays (:class:`~fusion.sim.scan.ScanData`),
  the fast path for Monte Carlo (no pydantic);
* :meth:`Simulator.run` — wire messages (``RadarSite``, sector ``PlotBatch``, ``Truth``)
  as :class:`SimEvent` in emission-time order, cut from the very same ScanData.

Each sensor draws from its own stream ``SeedSequence(seed, spawn_key=(1, i))``, so
iterating ``scans()`` or ``run()`` again, or for another sensor, gives identical plots.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import pymap3d
from skyfuse.schemas import PlotBatch, RadarBias, RadarSite, Truth, keys

from .cartesian import cartesian_scan
from .radar import radar_scan
from .reports import report_fleet, report_scan
from .scan import REPORT_COLUMNS, ScanData
from .scenario import Scenario

_RANK = {"site": 0, "truth": 1, "plots": 2}


def _secondary_columns(scan: ScanData, sl: slice) -> dict[str, list]:
    """The PlotBatch secondary-surveillance columns of plots ``sl`` of a scan (null for
    NaN, -1 and ""; the flags as booleans)."""
    out: dict[str, list] = {}
    for name, v in (scan.secondary or {}).items():
        part = v[sl]
        if part.dtype.kind == "b":
            out[name] = part.tolist()
        elif part.dtype.kind == "f":
            out[name] = [None if x != x else x for x in part.tolist()]
        elif part.dtype.kind == "O":
            out[name] = [x or None for x in part.tolist()]
        else:
            out[name] = [None if x < 0 else x for x in part.tolist()]
    return out


@dataclass(frozen=True)
class SimEvent:
    """One simulator output: ``time`` (emission time, ns UTC), ``kind`` ("site",
    "plots" or "truth"), the key-space ``topic`` and the wire ``message``."""

    time: int
    kind: str
    topic: str
    message: Any


class Simulator:
    """Seeded, deterministic scenario simulator (``seed`` defaults to the scenario's)."""

    def __init__(self, scenario: Scenario, seed: int | None = None) -> None:
        self.scenario = scenario
        self.seed = scenario.seed if seed is None else int(seed)
        if self.seed < 0:
            raise ValueError(f"seed = {self.seed}: must be >= 0")

    # --- fast path ----------------------------------------------------------------------
    def _rng(self, index: int) -> np.random.Generator:
        return np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(1, index)))

    def _reply_rng(self, index: int) -> np.random.Generator:
        """Sensor ``index``'s stream for its replies' identity data (garbling): separate
        from its plots' stream, so identity never changes the plots of a seed."""
        return np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(3, index)))

    def sensor_scans(self, index: int) -> Iterator[ScanData]:
        """All scans of sensor ``index`` (in ``scenario.sensors``) in time order."""
        sc = self.scenario
        cfg = sc.sensors[index]
        rng = self._rng(index)
        scans = cfg.scans_in(sc.duration)
        if cfg.reports:
            fleet = report_fleet(cfg, sc.targets, rng)
            for k in scans:
                yield report_scan(cfg, k, sc.targets, sc.geodetic, rng, sc.start_time, fleet,
                                  index)  # fmt: skip
        elif cfg.site.kind == "cartesian":
            # all snapshot positions at once (same numbers as per scan, less overhead)
            times = np.array([cfg.scan_time(k) for k in scans])[:, None]
            tgt = np.arange(len(sc.targets))[None, :]
            pos, _ = sc.targets.state(times, tgt)
            alive = sc.targets.alive(times, tgt)
            for j, k in enumerate(scans):
                truth = (alive[j], pos[j])
                yield cartesian_scan(cfg, k, sc.targets, rng, sc.start_time, index, truth)
        else:
            replies = self._reply_rng(index)
            for k in scans:
                yield radar_scan(cfg, k, sc.targets, sc.geodetic, rng, sc.start_time, index,
                                 identity_rng=replies)  # fmt: skip

    def scans(self, radar_id: str | None = None) -> Iterator[ScanData]:
        """Per-scan arrays of all sensors (or one, by ``radar_id``), ordered by scan end
        time (ties by sensor order)."""
        ids = [s.radar_id for s in self.scenario.sensors]
        if radar_id is not None and radar_id not in ids:
            raise ValueError(f"radar_id {radar_id!r} is not in this scenario; radars: {ids}")
        streams = [
            ((s.time_end, i, s.scan, s) for s in self.sensor_scans(i))
            for i, rid in enumerate(ids)
            if radar_id in (None, rid)
        ]
        for *_, scan in heapq.merge(*streams, key=lambda e: e[:3]):
            yield scan

    # --- messages -----------------------------------------------------------------------
    @staticmethod
    def sector_batches(scan: ScanData, first_seq: int) -> list[PlotBatch]:
        """Cut one scan into its sector ``PlotBatch``es (seq from ``first_seq``)."""
        n_sec = scan.n_sectors
        edges = np.searchsorted(scan.sector, np.arange(n_sec + 1), side="left")
        width = 2 * math.pi / n_sec
        out = []
        for j in range(n_sec):
            sl = slice(edges[j], edges[j + 1])
            cols: dict[str, Any] = {
                "time": scan.time[sl].tolist(),
                "target_id": scan.target_id[sl].tolist(),
            }
            if scan.x is None and scan.lat is None:
                cols["range"] = scan.range[sl].tolist()
                cols["azimuth"] = scan.azimuth[sl].tolist()
            for name in ("x", "y", *REPORT_COLUMNS, "elevation", "altitude"):
                v = getattr(scan, name)
                if v is not None:
                    part = v[sl].tolist()
                    cols[name] = (
                        [None if x != x else x for x in part] if np.isnan(v[sl]).any() else part
                    )
            for name in ("mode_s", "mode_3a"):
                v = getattr(scan, name)
                if v is not None:
                    cols[name] = [None if c < 0 else c for c in v[sl].tolist()]
            cols.update(_secondary_columns(scan, sl))
            out.append(
                PlotBatch(
                    radar_id=scan.radar_id,
                    scan=scan.scan,
                    seq=first_seq + j,
                    sector_start=0.0 if n_sec == 1 else j * width,
                    sector_width=2 * math.pi if n_sec == 1 else width,
                    time_start=int(scan.sector_bounds[j]),
                    time_end=int(scan.sector_bounds[j + 1]),
                    **cols,
                )
            )
        return out

    def _plot_events(self, index: int) -> Iterator[tuple]:
        site: RadarSite = self.scenario.sensors[index].site
        topic = keys.radar_plots(site.radar_id)
        seq = 0
        for scan in self.sensor_scans(index):
            for batch in self.sector_batches(scan, seq):
                yield (batch.time_end, _RANK["plots"], index, batch.seq,
                       SimEvent(batch.time_end, "plots", topic, batch))  # fmt: skip
            seq += scan.n_sectors

    def truth_times(self) -> np.ndarray:
        """Times of the Truth messages: start + j·truth_period up to the duration, ns."""
        sc = self.scenario
        n = math.floor(sc.duration / sc.truth_period + 1e-9)
        return sc.start_time + np.rint(np.arange(n + 1) * sc.truth_period * 1e9).astype(np.int64)

    def _truth_events(self) -> Iterator[tuple]:
        for j, t in enumerate(self.truth_times()):
            msg = self.truth_message(int(t))
            yield (int(t), _RANK["truth"], -1, j, SimEvent(int(t), "truth", keys.SIM_TRUTH, msg))

    def run(self, radars: Iterable[str] | None = None, *, truth: bool = True) -> Iterator[SimEvent]:
        """All events in non-decreasing time: the sites at the start time, Truth every
        ``truth_period``, and every sensor's sector batches, each emitted when the beam
        leaves its sector (``time_end``; the cartesian sensor: at the scan time). Ties:
        sites, then truth, then plots in sensor order.

        ``radars`` restricts the sites and plots to those radar ids (e.g. one sensor
        process publishing one radar; the other radars are then not simulated at all, and
        the numbers are the same as in a full run); ``truth=False`` leaves out Truth."""
        sc = self.scenario
        ids = [s.radar_id for s in sc.sensors]
        wanted = set(ids) if radars is None else set(radars)
        unknown = sorted(wanted - set(ids))
        if unknown:
            raise ValueError(f"radar_id {unknown[0]!r} is not in this scenario; radars: {ids}")
        for site in sc.sites:
            if site.radar_id in wanted:
                yield SimEvent(sc.start_time, "site", keys.radar_site(site.radar_id), site)
        streams = [self._plot_events(i) for i, rid in enumerate(ids) if rid in wanted]
        if truth:
            streams.append(self._truth_events())
        for *_, ev in heapq.merge(*streams, key=lambda e: e[:4]):
            yield ev

    # --- truth --------------------------------------------------------------------------
    def truth_at(self, times_ns, geodetic: bool = True) -> dict[str, np.ndarray]:
        """Ground truth of every target at ``times_ns`` (int ns UTC, shape (m,)).

        Returns arrays of shape (m, n_targets) (``target_id`` (n,), ``time`` (m,)):
        ``x``, ``y`` (m, scenario/system plane), ``z`` (= ``alt``, m above WGS-84), ``vx``,
        ``vy``, ``vz`` (m/s in the plane), ``alive`` (bool), and with ``geodetic``:
        ``lat``, ``lon`` (deg), ``vel_east``, ``vel_north``, ``vel_up`` (m/s; for planar
        scenarios the plane components, for the stereographic plane corrected for grid
        convergence and scale)."""
        sc = self.scenario
        times_ns = np.atleast_1d(np.asarray(times_ns, np.int64))
        t = (times_ns - sc.start_time) * 1e-9
        n = len(sc.targets)
        tt = np.repeat(t[:, None], n, axis=1)
        idx = np.broadcast_to(np.arange(n), tt.shape)
        p, v = sc.targets.state(tt, idx)
        out = {
            "time": times_ns,
            "target_id": sc.targets.target_id.copy(),
            "x": p[..., 0],
            "y": p[..., 1],
            "z": p[..., 2],
            "alt": p[..., 2],
            "vx": v[..., 0],
            "vy": v[..., 1],
            "vz": v[..., 2],
            "alive": sc.targets.alive(tt, idx),
        }
        if geodetic:
            lat, lon = sc.plane.inverse(p[..., 0], p[..., 1])
            out["lat"], out["lon"] = np.asarray(lat), np.asarray(lon)
            if sc.planar:
                out["vel_east"], out["vel_north"] = v[..., 0], v[..., 1]
            else:
                lat2, lon2 = sc.plane.inverse(p[..., 0] + v[..., 0], p[..., 1] + v[..., 1])
                e, nn, _ = pymap3d.geodetic2enu(lat2, lon2, p[..., 2], lat, lon, p[..., 2])
                out["vel_east"], out["vel_north"] = np.asarray(e), np.asarray(nn)
            out["vel_up"] = v[..., 2]
        return out

    def truth_message(self, time_ns: int) -> Truth:
        """``Truth`` of the targets alive at ``time_ns`` (x/y only for planar scenarios)
        and the radars' systematic errors."""
        d = self.truth_at(np.array([time_ns]))
        a = d["alive"][0]
        planar = self.scenario.planar
        return Truth(
            time=int(time_ns),
            target_id=d["target_id"][a].tolist(),
            lat=d["lat"][0, a].tolist(),
            lon=d["lon"][0, a].tolist(),
            alt=d["alt"][0, a].tolist(),
            vel_east=d["vel_east"][0, a].tolist(),
            vel_north=d["vel_north"][0, a].tolist(),
            vel_up=d["vel_up"][0, a].tolist(),
            x=d["x"][0, a].tolist() if planar else None,
            y=d["y"][0, a].tolist() if planar else None,
            radar_bias=self.radar_biases(),
        )

    def radar_biases(self) -> list[RadarBias]:
        """The systematic errors of the radars that have any (``Truth.radar_bias``)."""
        out = []
        for cfg in self.scenario.sensors:
            b = cfg.bias
            if not b.is_zero:
                out.append(
                    RadarBias(radar_id=cfg.site.radar_id, azimuth=b.azimuth, range=b.range,
                              range_gain=b.range_gain, time=b.time)
                )  # fmt: skip
        return out
