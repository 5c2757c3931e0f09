"""Helpers shared by the tests (real processes and Zenoh sessions on loopback, synthetic
sites and batches) and the paths they read. Not a test module: tests import it by name
(``pythonpath = ["tests"]`` in pyproject.toml; pytest runs with ``--import-mode=importlib``).

``SHARED_DATA``: the public data of the project's data README (the 7-radar ASTERIX
snippet, the CAT062 sample, the Barcelona traffic), ``../shared/data`` next to the
repository or ``$SKYFUSE_SHARED_DATA``; tests that need it skip when it is absent.

:func:`independent_asterix_decode`: ASTERIX decoded by an independent decoder
(asterix-decoder, CroatiaControl's C++ decoder, in a virtualenv of its own)."""

from __future__ import annotations

import fcntl
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
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


def last_payload(inbox, seconds: float, parse=json.loads):
    """The last payload an ``Inbox`` receives within ``seconds``, parsed by ``parse``
    (JSON by default, e.g. ``Status.from_json_bytes``); None when nothing arrived."""
    out, end = None, time.monotonic() + seconds
    while time.monotonic() < end:
        item = inbox.get(0.1)
        if item is not None:
            out = parse(item.payload)
    return out


BIASED_TRUTH = {"LYVR": (0.2, 150.0), "LRTR": (-0.15, -100.0)}
"""Azimuth (deg) and range (m) biases of the biased regional recording."""
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


# --- an independent ASTERIX decoder ---------------------------------------------------
ASTERIX_DECODER = "asterix-decoder==0.7.11"
"""The independent decoder (PyPI ``asterix-decoder``, CroatiaControlLtd/asterix: GPL, a
C++ extension; needs g++ and libexpat1-dev to build). It installs a top-level ``asterix``
package, as libasterix does, so it lives in a virtualenv of its own and runs in a
subprocess: it never enters skyfuse's environment."""
ASTERIX_DECODER_VENV = Path(
    os.environ.get("SKYFUSE_ASTERIX_DECODER_VENV")
    or Path(tempfile.gettempdir()) / "skyfuse-asterix-decoder-0.7.11"
)
"""Where that virtualenv is made, once, and kept for later sessions
(``$SKYFUSE_ASTERIX_DECODER_VENV``, default in the system's temporary directory)."""


class IndependentDecoderUnavailable(RuntimeError):
    """asterix-decoder could not be installed here (the message says why)."""


_decoder_failure: str | None = None


def independent_decoder_python(timeout: float = 900.0) -> Path:
    """The Python of the asterix-decoder virtualenv, made on first use (a file lock
    keeps concurrent test sessions from building it twice; a half-made one is never
    used: it is built aside and renamed). Raises :class:`IndependentDecoderUnavailable`."""
    global _decoder_failure
    if _decoder_failure is not None:
        raise IndependentDecoderUnavailable(_decoder_failure)
    venv = ASTERIX_DECODER_VENV
    python = venv / "bin" / "python"
    if python.exists():
        return python
    venv.parent.mkdir(parents=True, exist_ok=True)
    with open(f"{venv}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if python.exists():
            return python
        work = Path(f"{venv}.building")
        shutil.rmtree(work, ignore_errors=True)
        steps = (
            [sys.executable, "-m", "venv", str(work)],
            [str(work / "bin" / "python"), "-m", "pip", "install", "-q", ASTERIX_DECODER],
        )
        for cmd in steps:
            try:
                done = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
            except (OSError, subprocess.TimeoutExpired) as e:
                done = None
                error = f"{type(e).__name__}: {e}"
            if done is None or done.returncode != 0:
                tail = error if done is None else (done.stderr or done.stdout)[-800:]
                _decoder_failure = f"{' '.join(cmd[-2:])} failed: {tail.strip()}"
                shutil.rmtree(work, ignore_errors=True)
                raise IndependentDecoderUnavailable(_decoder_failure)
        work.rename(venv)
    return python


_DECODE_SCRIPT = """
import json, sys
import asterix
for definition in sys.argv[2:]:
    asterix.init(definition)
data = open(sys.argv[1], "rb").read()
json.dump(asterix.parse(data, verbose=False), sys.stdout, default=str)
"""


def independent_asterix_decode(
    data: bytes | str | Path, definitions: tuple[Path, ...] = ()
) -> list[dict]:
    """ASTERIX data blocks (bytes, or a raw ``.ast`` file) decoded by asterix-decoder:
    one dict per record, as that decoder gives it (``category``, then ``I010``,
    ``I140``, … each a dict of subfields ``{"val": …}``; repetitive items as lists).
    Its editions: CAT048 1.21, CAT062 1.18, CAT034 1.27, CAT021 2.6, CAT010 1.1, …
    (``asterix.list_configuration_files()``); ``definitions``: extra XML category
    definitions loaded with ``asterix.init`` first. Raises IndependentDecoderUnavailable."""
    python = independent_decoder_python()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(data) if isinstance(data, (str, Path)) else Path(tmp) / "blocks.ast"
        if not isinstance(data, (str, Path)):
            path.write_bytes(bytes(data))
        env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
        cmd = [str(python), "-c", _DECODE_SCRIPT, str(path), *map(str, definitions)]
        done = subprocess.run(cmd, capture_output=True, timeout=600, env=env, cwd=tmp)
    if done.returncode != 0:
        raise RuntimeError(f"asterix-decoder failed: {done.stderr.decode()[-800:]}")
    return json.loads(done.stdout)


LEBL_SITES_TOML = """
[[radar]]
sac = 0
sic = 107
lat = 41.29706278
lon = 2.07844722
alt = 4.0
[[radar]]
sac = 0
sic = 7
lat = 41.29561833
lon = 2.09511417
alt = 4.0
"""
"""The Barcelona–El Prat sensors of the shared LEBL recordings as a sites TOML: the
multilateration (SAC 0 / SIC 107) and the surface movement radar (SAC 0 / SIC 7)."""


def confirmed_ids(b) -> list[int]:
    """The ids of the confirmed tracks of a ``TrackBatch``, sorted."""
    return sorted(t.track_id for t in b.tracks if t.status == "confirmed")


def feed_pictures(feed: list) -> list[tuple[int, object]]:
    """(plot batches applied so far, the rebuilt picture as a ``TrackBatch``) after each
    delta of a fusion ``feed`` (``schemas.TrackPicture``)."""
    from skyfuse.schemas import FeedKind, TrackPicture

    pic, n, out = TrackPicture(), 0, []
    for b in feed:
        pic.apply(b)
        if b.kind is FeedKind.DELTA:
            n += b.batches
            out.append((n, pic.batch()))
    return out
