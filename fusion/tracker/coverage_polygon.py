"""A sensor's coverage as a polygon in the system plane: signed distance and the share of a
Gaussian position inside it.

The polygon (vertices v_0 … v_{V−1} in order, closed implicitly, m) is the sensor site's
``coverage`` (WGS-84 vertices) converted into the frame. For points p (n, 2):

* inside by the even-odd rule: a ray from p towards +x crosses an odd number of edges
  (each edge (a, b) counts when (a_y > p_y) ≠ (b_y > p_y) and p_x < a_x + (p_y − a_y)
  (b_x − a_x)/(b_y − a_y));
* the distance to the boundary, the smallest distance to an edge segment
  ‖p − (a + clip(t, 0, 1)(b − a))‖ with t = (p − a)·(b − a)/‖b − a‖²;
* the signed distance d (positive inside, negative outside).

The *share* of a track whose position is Gaussian with per-axis σ about p is
Φ(d/σ): the probability of being inside the half-plane of the nearest edge, exact for a
straight boundary far from the vertices and a good approximation of the probability of
being inside the polygon whenever σ is small compared with the polygon (a coverage is
kilometres across; an airport surface track's σ is metres).

Everything is vectorised over points × edges (n × V); a coverage has tens of vertices.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtr


def inside(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """(n,) bool: the points (n, 2) inside the polygon ``vertices`` (V, 2), even-odd rule."""
    p = np.atleast_2d(points)
    a = vertices
    b = np.roll(vertices, -1, axis=0)
    py = p[:, 1:2]
    straddle = (a[None, :, 1] > py) != (b[None, :, 1] > py)
    dy = np.where(b[:, 1] != a[:, 1], b[:, 1] - a[:, 1], 1.0)
    x_cross = a[None, :, 0] + (py - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / dy[None, :]
    crossings = (straddle & (p[:, 0:1] < x_cross)).sum(axis=1)
    return crossings % 2 == 1


def boundary_distance(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """(n,) the distance of each point (n, 2) to the polygon's boundary, m."""
    p = np.atleast_2d(points)[:, None, :]
    a = vertices[None, :, :]
    ab = np.roll(vertices, -1, axis=0)[None, :, :] - a
    length2 = np.maximum((ab**2).sum(axis=-1), 1e-12)
    t = np.clip(((p - a) * ab).sum(axis=-1) / length2, 0.0, 1.0)
    nearest = a + t[..., None] * ab
    return np.sqrt(((p - nearest) ** 2).sum(axis=-1)).min(axis=1)


def signed_distance(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """(n,) the signed distance of each point to the boundary: positive inside, m."""
    d = boundary_distance(points, vertices)
    return np.where(inside(points, vertices), d, -d)


def share_inside(points: np.ndarray, sigma: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """(n,) Φ(d/σ): the share of a Gaussian position (per-axis ``sigma`` (n,) m) inside."""
    s = np.maximum(np.asarray(sigma, dtype=np.float64), 1e-3)
    return ndtr(signed_distance(points, vertices) / s)
