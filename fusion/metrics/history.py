"""Columnar per-scan histories of tracks and truth, the input of the MTT measures.

One row per (run, scan, track) and per (run, scan, target), as flat NumPy columns, so the
measures of ``mtt_measures`` and ``retention`` are vectorised over a whole Monte Carlo
experiment. Scans are integer scan numbers (the thesis counts 1..40); runs are Monte Carlo
run indices. Track ids must be unique within an experiment: a false track carried over
into the next run ([thesis] §7.1) keeps its id, a new track never re-uses one.
Labels are those of ``labelling.TruthLabeller`` (target id, or ``FALSE`` = −1).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .labelling import FALSE


def _int_col(name: str, a: np.ndarray, n: int) -> np.ndarray:
    a = np.asarray(a)
    if a.size == 0:
        a = a.astype(np.int64).reshape(0)
    if a.shape != (n,) or not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"{name}: shape {a.shape}, dtype {a.dtype}: must be ({n},) integers")
    return a.astype(np.int64)


def _pos_col(name: str, a: np.ndarray, n: int) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.size == 0 and n == 0:
        return a.reshape(0, a.shape[1] if a.ndim == 2 else 2)
    if a.ndim != 2 or len(a) != n:
        raise ValueError(f"{name}: shape {a.shape}: must be ({n}, d) positions")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: contains non-finite values: positions must be finite")
    return a


@dataclass(frozen=True)
class TrackHistory:
    """Tracks per scan: ``run``, ``scan``, ``track_id`` (r,) int; ``confirmed`` (r,) bool;
    ``label`` (r,) int target id or ``FALSE``; ``position`` (r, d) metres (system plane);
    ``existence`` (r,) ψ_{k|k} (optional, NaN if unknown; used to pick among duplicates)."""

    run: np.ndarray
    scan: np.ndarray
    track_id: np.ndarray
    confirmed: np.ndarray
    label: np.ndarray
    position: np.ndarray
    existence: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        n = len(np.asarray(self.run).reshape(-1))
        object.__setattr__(self, "run", _int_col("run", self.run, n))
        object.__setattr__(self, "scan", _int_col("scan", self.scan, n))
        object.__setattr__(self, "track_id", _int_col("track_id", self.track_id, n))
        object.__setattr__(self, "label", _int_col("label", self.label, n))
        conf = np.asarray(self.confirmed)
        if conf.shape != (n,) or conf.dtype != bool:
            raise ValueError(
                f"confirmed: shape {conf.shape}, dtype {conf.dtype}: must be ({n},) bool"
            )
        object.__setattr__(self, "confirmed", conf)
        object.__setattr__(self, "position", _pos_col("position", self.position, n))
        ex = np.full(n, np.nan) if self.existence is None else np.asarray(self.existence, float)
        if ex.shape != (n,):
            raise ValueError(f"existence: shape {ex.shape}: must be ({n},)")
        object.__setattr__(self, "existence", ex)
        if np.any(self.label < FALSE):
            raise ValueError(f"label: value {int(self.label.min())}: must be a target id or -1")

    def __len__(self) -> int:
        return len(self.run)

    @classmethod
    def concat(cls, parts: list[TrackHistory]) -> TrackHistory:
        """Stack histories (e.g. one per scan or per run) into one."""
        if not parts:
            return cls(
                *(np.zeros(0, np.int64),) * 3,
                np.zeros(0, bool),
                np.zeros(0, np.int64),
                np.zeros((0, 2)),
            )
        return cls(
            run=np.concatenate([h.run for h in parts]),
            scan=np.concatenate([h.scan for h in parts]),
            track_id=np.concatenate([h.track_id for h in parts]),
            confirmed=np.concatenate([h.confirmed for h in parts]),
            label=np.concatenate([h.label for h in parts]),
            position=np.concatenate([h.position for h in parts]),
            existence=np.concatenate([h.existence for h in parts]),
        )

    @property
    def confirmed_true(self) -> np.ndarray:
        """Mask of rows with a confirmed track labelled true."""
        return self.confirmed & (self.label != FALSE)


@dataclass(frozen=True)
class TruthHistory:
    """Targets per scan: ``run``, ``scan``, ``target_id`` (r,) int (>= 0); ``position`` (r, d)."""

    run: np.ndarray
    scan: np.ndarray
    target_id: np.ndarray
    position: np.ndarray

    def __post_init__(self) -> None:
        n = len(np.asarray(self.run).reshape(-1))
        object.__setattr__(self, "run", _int_col("run", self.run, n))
        object.__setattr__(self, "scan", _int_col("scan", self.scan, n))
        object.__setattr__(self, "target_id", _int_col("target_id", self.target_id, n))
        object.__setattr__(self, "position", _pos_col("position", self.position, n))
        if np.any(self.target_id < 0):
            raise ValueError(f"target_id: value {int(self.target_id.min())}: must be >= 0")

    def __len__(self) -> int:
        return len(self.run)

    @classmethod
    def concat(cls, parts: list[TruthHistory]) -> TruthHistory:
        """Stack histories (e.g. one per scan or per run) into one."""
        if not parts:
            return cls(*(np.zeros(0, np.int64),) * 3, np.zeros((0, 2)))
        return cls(
            run=np.concatenate([h.run for h in parts]),
            scan=np.concatenate([h.scan for h in parts]),
            target_id=np.concatenate([h.target_id for h in parts]),
            position=np.concatenate([h.position for h in parts]),
        )


def joint_keys(*columns: tuple[np.ndarray, ...]) -> list[np.ndarray]:
    """Encode several tables' key columns as one int64 per row with a shared mixed radix.

    ``columns`` is one tuple of equal-length integer columns per table, all tables having
    the same number of columns; equal rows get equal keys across tables."""
    ncol = len(columns[0])
    lows, radices = [], []
    for c in range(ncol):
        vals = [np.asarray(t[c], dtype=np.int64) for t in columns]
        allv = np.concatenate(vals) if vals else np.zeros(0, np.int64)
        lo = int(allv.min()) if allv.size else 0
        hi = int(allv.max()) if allv.size else 0
        lows.append(lo)
        radices.append(hi - lo + 1)
    if float(np.prod(np.array(radices, dtype=float))) >= 2.0**62:
        raise ValueError(f"key ranges {radices}: too large to encode as one int64 key")
    keys = []
    for t in columns:
        k = np.zeros(len(t[0]), dtype=np.int64)
        for c in range(ncol):
            k = k * radices[c] + (np.asarray(t[c], dtype=np.int64) - lows[c])
        keys.append(k)
    return keys
