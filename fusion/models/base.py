"""The motion-model interface shared by filters and trackers."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class MotionModel(Protocol):
    """A linear(ised) discrete-time motion model x_k = F(dt) x_{k-1} + w, w ~ N(0, Q(dt)).

    ``labels`` names the state components in order (e.g. ``("x", "vx", "y", "vy")``);
    ``position_index`` gives the indices of the position components in that order."""

    labels: tuple[str, ...]
    position_index: tuple[int, ...]

    @property
    def dim(self) -> int: ...

    def F(self, dt: float | np.ndarray) -> np.ndarray: ...

    def Q(self, dt: float | np.ndarray) -> np.ndarray: ...


def as_dt_array(dt: float | np.ndarray) -> tuple[np.ndarray, bool]:
    """Return ``dt`` as a 1-D float array and whether the input was a scalar."""
    arr = np.asarray(dt, dtype=np.float64)
    return arr.reshape(-1), arr.ndim == 0


def states_and_dt(x: np.ndarray, dt: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """States x as a C-contiguous float64 (n, d) array and dt (a scalar, or one value per
    state) s as a C-contiguous float64 (n,) array: the one signature the models' compiled
    loops are compiled for."""
    x = np.ascontiguousarray(np.atleast_2d(x), dtype=np.float64)
    t = np.asarray(dt, dtype=np.float64).reshape(-1)
    if len(t) != len(x):  # a scalar (or one value) for every state
        t = np.broadcast_to(t, (len(x),))
    return x, np.ascontiguousarray(t)
