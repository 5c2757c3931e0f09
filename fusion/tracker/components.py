"""Track mixtures in flat arrays: Singer N-scan merge and pruning ([thesis] ch. 5); the moment
matching itself is :mod:`fusion.filters.moment_matching`.

Every track is a Gaussian mixture {ξ^c, x̂^c, P^c, h^c}. All components of all tracks
live in one :class:`Mixture`: ``track`` (C,) says which track row a component belongs to,
``hist`` (C, N) holds the ids of the plots the component used over the last N scans
(0 = no plot), most recent first. The grouping, merge and pruning are compiled loops
(:mod:`.components_kernel`), so no Python loop runs over components.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skyfuse.fusion.filters.moment_matching import moment_match, segment_sum

from . import components_kernel as kernel

__all__ = [
    "Mixture",
    "components_per_track",
    "history_groups",
    "moment_match",
    "normalise",
    "prune",
    "prune_indices",
    "segment_sum",
    "singer_merge",
    "track_estimates",
]


@dataclass
class Mixture:
    """Flat component store: track (C,), w (C,), x (C, d), P (C, d, d), hist (C, N)."""

    track: np.ndarray
    w: np.ndarray
    x: np.ndarray
    P: np.ndarray
    hist: np.ndarray

    @classmethod
    def empty(cls, dim: int, depth: int) -> Mixture:
        return cls(
            np.zeros(0, np.int64),
            np.zeros(0),
            np.zeros((0, dim)),
            np.zeros((0, dim, dim)),
            np.zeros((0, depth), np.int64),
        )

    def __len__(self) -> int:
        return len(self.w)

    def take(self, idx: np.ndarray) -> Mixture:
        return Mixture(self.track[idx], self.w[idx], self.x[idx], self.P[idx], self.hist[idx])

    @staticmethod
    def concat(parts: list[Mixture]) -> Mixture:
        return Mixture(
            np.concatenate([p.track for p in parts]),
            np.concatenate([p.w for p in parts]),
            np.concatenate([p.x for p in parts]),
            np.concatenate([p.P for p in parts]),
            np.concatenate([p.hist for p in parts]),
        )


def singer_merge(mix: Mixture) -> Mixture:
    """Singer N-scan memory ([thesis] §5.3): merge, per track, all components whose
    last-N-scan plot histories are equal. Depth 0 (no history columns) merges every track
    into one Gaussian, i.e. IPDA. Resulting counts: C_k = 1+m_k (N=1),
    (1+m_k)(1+m_{k−1}) (N=2) when every component selects every plot (5.26, 5.1a).
    Compiled (:func:`~.components_kernel.singer_merge`)."""
    if len(mix) == 0:
        return mix
    return Mixture(*kernel.singer_merge(*_contiguous(mix)))


def _contiguous(mix: Mixture) -> tuple:
    c = np.ascontiguousarray
    return (c(mix.track, dtype=np.int64), c(mix.w, dtype=np.float64),
            c(mix.x, dtype=np.float64), c(mix.P, dtype=np.float64),
            c(mix.hist, dtype=np.int64))  # fmt: skip


def normalise(mix: Mixture, ntracks: int) -> Mixture:
    """Scale weights so they sum to 1 within each track (Σ_c ξ^c = 1, [thesis] (4.71))."""
    if len(mix) == 0:
        return mix
    tot = np.bincount(mix.track, weights=mix.w, minlength=ntracks)
    mix.w = mix.w / np.where(tot[mix.track] > 0, tot[mix.track], 1.0)
    return mix


def prune_indices(
    track: np.ndarray, w: np.ndarray, threshold: float, max_per_track: int, ntracks: int
) -> tuple[np.ndarray, np.ndarray]:
    """Which components survive pruning, and their renormalised weights: delete ξ <
    ``threshold`` (keeping each track's strongest), keep at most ``max_per_track`` per
    track by weight ([IMPL]). Returns (kept indices, weights).
    Compiled (:func:`~.components_kernel.prune_indices`)."""
    c = np.ascontiguousarray
    return kernel.prune_indices(c(track, dtype=np.int64), c(w, dtype=np.float64),
                                float(threshold), int(max_per_track), int(ntracks))  # fmt: skip


def prune(mix: Mixture, threshold: float, max_per_track: int, ntracks: int) -> Mixture:
    """:func:`prune_indices` applied to a :class:`Mixture`."""
    if len(mix) == 0:
        return mix
    keep, w = prune_indices(mix.track, mix.w, threshold, max_per_track, ntracks)
    out = mix.take(keep)
    out.w = w
    return out


def history_groups(track: np.ndarray, hist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Singer N-scan groups: (group label per component, unique (track, hist) rows),
    grouped as ``np.unique(keys, axis=0)`` would (lexicographic), by one stable sort.
    Compiled (:func:`~.components_kernel.history_groups`)."""
    c = np.ascontiguousarray
    return kernel.history_groups(c(track, dtype=np.int64), c(hist, dtype=np.int64))


def track_estimates(mix: Mixture, ntracks: int) -> tuple[np.ndarray, np.ndarray]:
    """Moment-matched track output x̂ = Σξ x̂^c, P = Σξ(P^c + spread) (4.66-4.68)."""
    _, x, P = moment_match(mix.w, mix.x, mix.P, mix.track, ntracks)
    return x, P


def components_per_track(mix: Mixture, ntracks: int) -> np.ndarray:
    return np.bincount(mix.track, minlength=ntracks)
