"""OSPA: optimal sub-pattern assignment metric (Schuhmacher, Vo & Vo, "A consistent metric for
performance evaluation of multi-object filters", IEEE TSP 56(8), 2008, Def. 1 and eq. (4)).

OSPA and GOSPA over time (docs/how-to/evaluate.md). For X = {x_1..x_n}, Y = {y_1..y_m},
n <= m (otherwise swap), cut-off c > 0 and order 1 <= p < ∞::

    d̄_p^(c)(X, Y) = ( (1/m) · ( min_π Σ_{i=1..n} d^(c)(x_i, y_π(i))^p + c^p · (m − n) ) )^(1/p)

with d^(c)(x, y) = min(‖x − y‖, c), and d̄ = 0 when both sets are empty. It splits into a
localisation part ē_loc = ((1/m) min_π Σ d^(c)^p)^(1/p) and a cardinality part
ē_card = ((1/m) c^p (m − n))^(1/p) with d̄^p = ē_loc^p + ē_card^p (ibid., eq. (5)-(6)).
OSPA is symmetric in X and Y. It is GOSPA with α = 1 divided by max(n, m) inside the power.
Positions in metres (any consistent unit); the result is in the same unit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .point_pattern import check_cutoff_and_order, distance_matrix, optimal_assignment, pair_points


@dataclass(frozen=True)
class OspaResult:
    """OSPA of one scan: ``distance`` d̄, its ``localisation`` and ``cardinality`` parts
    (each in metres, distance**p = localisation**p + cardinality**p) and ``assignment``:
    for each point of the first set, the index of its partner in the second set, or −1."""

    distance: float
    localisation: float
    cardinality: float
    assignment: np.ndarray


def ospa(x: np.ndarray, y: np.ndarray, c: float, p: float = 2.0) -> OspaResult:
    """OSPA between point sets ``x`` (n, d) and ``y`` (m, d), cut-off ``c``, order ``p``.

    Raises ``ValueError`` for non-finite or mis-shaped positions or bad parameters."""
    check_cutoff_and_order(c, p)
    x, y = pair_points(x, y)
    n, m = len(x), len(y)
    assignment = np.full(n, -1, dtype=np.intp)
    big = max(n, m)
    if big == 0:
        return OspaResult(0.0, 0.0, 0.0, assignment)
    rows, cols, cost = optimal_assignment(distance_matrix(x, y), c, p)
    assignment[rows] = cols
    loc = cost / big
    card = float(c) ** p * abs(m - n) / big
    return OspaResult(
        distance=float((loc + card) ** (1.0 / p)),
        localisation=float(loc ** (1.0 / p)),
        cardinality=float(card ** (1.0 / p)),
        assignment=assignment,
    )
