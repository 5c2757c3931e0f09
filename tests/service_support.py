"""Helpers shared by the tests (real processes and Zenoh sessions on loopback, synthetic
sites and batches) and the paths they read. Not a test module: tests import it by name
(``pythonpath = ["tests"]`` in pyproject.toml; pytest runs with ``--import-mode=importlib``).

``SHARED_DATA``: the public data of the project's data README (the 7-radar ASTERIX
snippet, the CAT062 sample, the Barcelona traffic), ``../shared/data`` next to the
repository or ``$SKYFUSE_SHARED_DATA``; tests that need it skip when it is absent."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from skyfuse.schemas import PlotBatch, RadarKind, RadarSite, keys
from skyfuse.services.recording.mcap_io import RecordingWriter
from skyfuse.services.runtime.transport import TransportConfig, TransportError, open_session

ROOT = Path(__file__).resolve().parents[1]
"""The repository root."""
SHARED_DATA = Path(os.environ.get("SKYFUSE_SHARED_DATA", ROOT.parent / "shared" / "data"))
EPOCH = 1_700_000_000_000_000_000


def peer(listen: str | None = None, connect: str | None = None) -> TransportConfig:
    return TransportConfig(
        mode="peer", listen=[listen] if listen else [], connect=[connect] if connect else []
    )


def make_site(radar_id: str, lat: float, lon: float, n_sectors: int = 4) -> RadarSite:
    return RadarSite(
        radar_id=radar_id,
        lat=lat,
        lon=lon,
        alt=100.0,
        kind=RadarKind.TWO_D,
        scan_period=4.0,
        n_sectors=n_sectors,
    )


def make_batch(radar_id: str, scan: int, sector: int, n_sectors: int, n: int, rng) -> PlotBatch:
    period = 4_000_000_000
    width = 2 * math.pi / n_sectors
    t_start = EPOCH + scan * period + sector * period // n_sectors
    t_end = t_start + period // n_sectors
    az = np.sort(rng.uniform(sector * width, (sector + 1) * width, n))
    times = (t_start + (az - sector * width) / width * (t_end - t_start)).astype(np.int64)
    return PlotBatch(
        radar_id=radar_id,
        scan=scan,
        seq=scan * n_sectors + sector,
        sector_start=sector * width,
        sector_width=width,
        time_start=t_start,
        time_end=t_end,
        time=times.tolist(),
        range=rng.uniform(1e3, 1e5, n).tolist(),
        azimuth=az.tolist(),
        altitude=rng.uniform(1e3, 1e4, n).tolist(),
    )


def synthetic_recording(
    path: Path,
    radars: tuple[str, ...] = ("R1", "R2"),
    scans: int = 2,
    n_sectors: int = 4,
    plots: int = 5,
    seed: int = 0,
) -> dict[str, int]:
    """A small recording: sites at t0, then sector batches of every radar in time order.
    Returns the number of plot batches per radar."""
    rng = np.random.default_rng(seed)
    counts = dict.fromkeys(radars, 0)
    with RecordingWriter(path, metadata={"command": "test"}) as w:
        for i, r in enumerate(radars):
            w.write(keys.radar_site(r), make_site(r, 45.0 + 0.2 * i, 20.0, n_sectors), EPOCH)
        for scan in range(scans):
            for sector in range(n_sectors):
                for r in radars:
                    b = make_batch(r, scan, sector, n_sectors, plots, rng)
                    w.write(keys.radar_plots(r), b, b.time_end)
                    counts[r] += 1
    return counts


def skyfuse(*args: str, log_path: Path | None = None, env: dict | None = None) -> subprocess.Popen:
    """Start a ``skyfuse`` command as a process (stderr to ``log_path``) through
    ``python -m skyfuse.services.cli``, the ``skyfuse`` entry point (which imports only the
    named command's module)."""
    err = open(log_path, "wb") if log_path else subprocess.DEVNULL
    return subprocess.Popen(
        [sys.executable, "-m", "skyfuse.services.cli", *args],
        stdout=subprocess.PIPE,
        stderr=err,
        env={**os.environ, **(env or {})},
        cwd=ROOT,
    )


def stop(proc: subprocess.Popen, sig: int = signal.SIGTERM, timeout: float = 8.0):
    """Send ``sig``; return (exit code, seconds it took)."""
    t0 = time.monotonic()
    if proc.poll() is None:
        proc.send_signal(sig)
    try:
        rc = proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        rc = None
    return rc, time.monotonic() - t0


def wait_for(pred, timeout: float = 10.0, step: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(step)
    return bool(pred())


BIASED_TRUTH = {"LYVR": (0.2, 150.0), "LRTR": (-0.15, -100.0)}
"""Azimuth (deg) and range (m) biases of the biased regional recording (issue 17)."""
BIASED_REGIONAL = (
    "--scenario", "regional", "--seed", "4", "--duration", "200", "--targets", "15",
    "--param", "radars=3," + ",".join(
        f"{r}.bias_azimuth_deg={a},{r}.bias_range_m={d}" for r, (a, d) in BIASED_TRUTH.items()
    ) + ",LYVR.bias_time_ms=50",
)  # fmt: skip
"""``skyfuse simulate`` arguments of a small regional recording, three radars (LYBE,
LYVR, LRTR) of which two biased, for the registration tests (``simulated_recording``)."""


def wait_for_router(cfg: TransportConfig, timeout: float = 30.0) -> None:
    """Until a client session to the router opens (the router process is starting)."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            with open_session(cfg):
                return
        except TransportError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)
