"""A restarted simulated sensor continues where it stopped (docs/reliability.md, restarts).

The simulated radar's batches come from a deterministic scenario (fixed epoch, seed), so
a sensor restarted from the beginning would publish again, with the same ``seq``, every
batch it already published — duplicates that a recorder would store. Instead the sensor
keeps its progress in ``progress.json`` in its state directory (``--state-dir``, default
``$XDG_STATE_HOME/skyfuse/sensor-{radar}``): the last published ``seq`` and ``time_end``,
a fingerprint of the scenario selection, written atomically at most every
``PROGRESS_INTERVAL`` s and when stopped; a run that published its whole scenario removes
it, so only an interrupted run (a stop, a crash) is continued. At start, when the
fingerprint matches and the file is younger than ``resume_max_age`` (default 60 s), the
sensor skips the batches with ``time_end`` up to the saved one and maps the first
remaining one to its start instant: sequence numbers and times continue. A ``kill -9``
can lose the last ``PROGRESS_INTERVAL`` of progress, so at most that much is published twice — those
repeats have the identity ``(radar, epoch, seq)`` of the first copies, which the fusion
service and the recorder refuse as ``duplicate batch`` (``services.runtime.seen_batches``).

**Epochs** (``PlotBatch.epoch``): a sensor's numbering is identified by an epoch, kept
with the numbering, and a new epoch is the only way to number from anywhere else than
where the last number left off (receivers refuse a number far beyond what the radar can
have published since its last one: ``services.runtime.seen_batches``). The simulated
sensor's epoch is saved in ``progress.json`` (a continued run keeps it and continues its
numbers; a run from the beginning starts a new one: its start instant, ns); the live
ASTERIX sensor takes a new one at every start (its numbers then continue above the
ceiling of ``sequence.json``, with a gap of up to ``SEQ_RESERVE``); the ASTERIX file
sensor's is a fingerprint of the file and of how it is decoded (:func:`file_epoch`), so
publishing the same file again repeats the same ``(radar, epoch, seq)`` and is refused as
duplicates, batch by batch.
"""

from __future__ import annotations

import hashlib
import json
import logging
import time
from pathlib import Path

from skyfuse.services.runtime.state_files import atomic_write, state_home

log = logging.getLogger(__name__)

PROGRESS_INTERVAL = 1.0
"""Seconds between two writes of the progress file (wall clock)."""
_PACING_FIELDS = {
    "start_at", "align", "wait_for", "wait_timeout", "status_interval", "linger",
    "state_dir", "resume_max_age", "cache_batches",
}  # fmt: skip


def default_sensor_dir(radar_id: str) -> Path:
    return state_home() / f"sensor-{radar_id}"


def selection_fingerprint(cfg) -> str:
    """SHA-256 of what determines the batches (scenario, seed, parameters, radar, speed),
    not of the pacing or start options."""
    text = cfg.model_dump_json(exclude=_PACING_FIELDS)
    return hashlib.sha256(text.encode()).hexdigest()


class SensorProgress:
    """The progress file of one simulated sensor (see the module docstring)."""

    def __init__(self, directory: Path, fingerprint: str, max_age: float) -> None:
        self.dir = Path(directory)
        self.dir.mkdir(parents=True, exist_ok=True, mode=0o700)
        self.path = self.dir / "progress.json"
        self.fingerprint, self.max_age = fingerprint, max_age
        self.last: tuple[int, int] | None = None
        self._written = 0.0
        self.epoch = new_epoch()
        """The epoch of this run's numbering (the previous run's if continued)."""

    @classmethod
    def from_config(cls, cfg) -> SensorProgress | None:
        if cfg.resume_max_age is None:
            return None
        directory = cfg.state_dir or default_sensor_dir(cfg.radar)
        return cls(directory, selection_fingerprint(cfg), cfg.resume_max_age)

    def resume_after(self) -> int | None:
        """The ``time_end`` (ns) of the last batch published by the previous run of the
        same selection, if recent enough; ``None``: start from the beginning."""
        try:
            d = json.loads(self.path.read_text())
            fp, seq, t_end, written = d["fingerprint"], d["seq"], d["time_end"], d["written_ns"]
        except FileNotFoundError:
            return None
        except (ValueError, KeyError, TypeError) as e:
            log.warning("progress %s unreadable (%s): starting from the beginning", self.path, e)
            return None
        age = (time.time_ns() - int(written)) / 1e9
        if fp != self.fingerprint or age > self.max_age:
            why = "another scenario selection" if fp != self.fingerprint else f"{age:.0f} s old"
            log.info("progress %s not resumed (%s): starting from the beginning", self.path, why)
            return None
        log.info("continuing after seq %d (progress %.1f s old)", seq, age)
        self.last = (int(seq), int(t_end))
        epoch = d.get("epoch")
        if type(epoch) is int and epoch > 0:  # files of earlier versions have none
            self.epoch = epoch
        return int(t_end)

    def published(self, seq: int, time_end: int) -> None:
        """Note a published batch; write the file if ``PROGRESS_INTERVAL`` has passed."""
        self.last = (seq, time_end)
        if time.monotonic() - self._written >= PROGRESS_INTERVAL:
            self.write()

    def finished(self) -> None:
        """The whole scenario was published: forget the progress, so that the next run of
        the same selection (e.g. a second ``skyfuse demo``) starts from the beginning."""
        self.last = None
        try:
            self.path.unlink()
        except FileNotFoundError:
            pass
        except OSError as e:
            log.error("cannot remove %s: %s", self.path, e)

    def write(self) -> None:
        if self.last is None:
            return
        d = {"fingerprint": self.fingerprint, "seq": self.last[0], "time_end": self.last[1],
             "epoch": self.epoch, "written_ns": time.time_ns()}  # fmt: skip
        try:
            atomic_write(self.path, json.dumps(d).encode())
        except OSError as e:
            log.error("cannot write %s: %s", self.path, e)
        self._written = time.monotonic()


SEQ_RESERVE = 1000
"""Sequence numbers reserved by one write of ``sequence.json``."""


class SequenceCeiling:
    """Sequence numbers of a live sensor that never go back across restarts.

    A live ASTERIX feed (``--asterix-udp``) numbers each radar's batches from 0 in every
    run. This class shifts them by a per-radar base persisted in ``sequence.json`` of the
    sensor's state directory: before a batch is published with a number at or above the
    persisted ceiling, a new ceiling (that number + ``SEQ_RESERVE``) is written
    atomically; at start the base of each radar is its ceiling. So after a restart — even
    after ``kill -9`` — every radar's numbers continue above all numbers published
    before (with a gap of at most ``SEQ_RESERVE``), and a receiver can tell a repeat of
    an earlier batch (same ``seq``) from a new one."""

    def __init__(self, directory: Path) -> None:
        self.dir = Path(directory)
        self.dir.mkdir(parents=True, exist_ok=True, mode=0o700)
        self.path = self.dir / "sequence.json"
        self.epoch = new_epoch()
        """The epoch of this run's numbering: a new one at every start, since the numbers
        jump by up to ``SEQ_RESERVE`` (the ``@epoch`` of earlier versions' files is
        ignored)."""
        try:
            saved = json.loads(self.path.read_text())
            saved.pop(EPOCH_KEY, None)
            self.ceiling = {str(k): int(v) for k, v in saved.items()}
        except FileNotFoundError:
            self.ceiling = {}
        except (ValueError, TypeError, AttributeError) as e:
            log.warning("%s unreadable (%s): sequence numbers from 0", self.path, e)
            self.ceiling = {}
        self.base = dict(self.ceiling)

    def number(self, radar_id: str, seq: int) -> int:
        """The published sequence number of this run's batch number ``seq``."""
        out = self.base.get(radar_id, 0) + seq
        if out >= self.ceiling.get(radar_id, 0):
            self.ceiling[radar_id] = out + SEQ_RESERVE
            self._write()
        return out

    def _write(self) -> None:
        try:
            atomic_write(self.path, json.dumps(self.ceiling).encode())
        except OSError as e:
            log.error("cannot write %s: %s", self.path, e)


EPOCH_KEY = "@epoch"
"""The epoch's entry in ``sequence.json`` of earlier versions (no radar id contains
``@``); ignored."""


def new_epoch() -> int:
    """A new epoch: this instant, ns since the Unix epoch (UTC)."""
    return time.time_ns()


def file_epoch(path: Path, *selection) -> int:
    """The epoch of the batches decoded from a recording file: the first 60 bits of the
    SHA-256 of its content and of ``selection`` (what else determines the batches: the
    date, the sector count, …), never 0. The same file decoded the same way has the
    same epoch on every run and every host."""
    h = hashlib.sha256(repr(selection).encode())
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return int(h.hexdigest()[:15], 16) or 1
