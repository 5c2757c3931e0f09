"""Point-pattern helpers shared by OSPA and GOSPA: input checks, cut-off distances, assignment.

A point pattern is a finite set of points given as a float array of shape ``(n, d)``
(metres in skyfuse's system plane; any consistent unit works). ``n`` may be 0.
The base metric is the Euclidean distance; the cut-off distance is
``d^(c)(x, y) = min(‖x − y‖, c)`` (Schuhmacher et al. 2008, eq. (3);
Rahmathullah et al. 2017, §II).
"""

from __future__ import annotations

import numpy as np


def as_points(name: str, points: np.ndarray, dim: int | None = None) -> np.ndarray:
    """Return ``points`` as a finite float array of shape ``(n, d)``.

    A 1-D empty input is accepted as an empty pattern (``(0, dim)`` or ``(0, 0)``).
    Raises ``ValueError`` naming ``name`` when the shape, the dimension or a value is wrong.
    """
    arr = np.asarray(points, dtype=np.float64)
    if arr.size == 0 and arr.ndim <= 2:
        width = arr.shape[1] if arr.ndim == 2 else (dim or 0)
        return np.zeros((0, width))
    if arr.ndim != 2:
        raise ValueError(f"{name}: shape {arr.shape}: must be (n, d) points")
    if dim is not None and arr.shape[1] != dim:
        raise ValueError(f"{name}: dimension {arr.shape[1]}: must be {dim} like the other set")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"{name}[{bad[0]}, {bad[1]}] = {arr[tuple(bad)]}: must be finite")
    return arr


def check_cutoff_and_order(c: float, p: float) -> None:
    """Check the cut-off ``c > 0`` and order ``1 <= p < inf`` of OSPA/GOSPA."""
    if not (np.isfinite(c) and c > 0):
        raise ValueError(f"c = {c}: cut-off distance must be finite and > 0")
    if not (np.isfinite(p) and p >= 1):
        raise ValueError(f"p = {p}: order must be finite and >= 1")


def pair_points(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Validate two patterns and give them a common dimension (an empty one adopts the other's)."""
    x = as_points("x", x)
    y = as_points("y", y)
    if len(x) and len(y) and x.shape[1] != y.shape[1]:
        raise ValueError(f"y: dimension {y.shape[1]}: must be {x.shape[1]} like x")
    d = x.shape[1] if len(x) else y.shape[1]
    return x.reshape(len(x), d), y.reshape(len(y), d)


def distance_matrix(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Euclidean distances ``D[i, j] = ‖x_i − y_j‖``, shape ``(n, m)``."""
    diff = x[:, None, :] - y[None, :, :]
    return np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))


def optimal_assignment(
    dist: np.ndarray, c: float, p: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """Minimise ``Σ min(D[i, π(i)], c)^p`` over assignments of size ``min(n, m)``.

    Uses ``scipy.optimize.linear_sum_assignment`` (exact; rectangular matrices allowed).
    Returns ``(rows, cols, cost)`` with ``cost`` the minimal sum of cut-off distances
    to the power ``p``."""
    if dist.size == 0:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty, 0.0
    cost = np.minimum(dist, c) ** p
    from scipy.optimize import linear_sum_assignment  # 0.5 s import: only when used

    rows, cols = linear_sum_assignment(cost)
    return rows, cols, float(cost[rows, cols].sum())
