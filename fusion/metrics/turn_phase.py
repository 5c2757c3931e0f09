"""Turn / straight-flight split of truth samples, for position errors by flight phase
(the "RMSE during turns" of the regional scenario).

The truth of a simulated recording carries each target's horizontal velocity
v = (v_east, v_north) (m/s) at every truth time, not its manoeuvre. The turn rate of a
target between two consecutive truth samples k-1, k (Δt = t_k - t_{k-1}, s) is the
signed heading change per second [IMPL]:

    ω_k = atan2(v_{k-1} × v_k, v_{k-1} · v_k) / Δt        (rad/s, positive counter-clockwise)

with v × w = v_e w_n - v_n w_e. Sample k is *in a turn* when |ω_k| ≥ ω_min. The default
ω_min = 0.5 °/s is a sixth of a standard-rate turn (3 °/s): at 200 m/s it is a lateral
acceleration ω v = 1.75 m/s² (0.18 g), above any wind or speed-change effect of straight
flight and below the 1.5-3 °/s turns of the regional scenario's waypoints.

:func:`phase_rmse` gives the RMSE of position errors split by that flag. Pure arrays in,
plain dict out.
"""

from __future__ import annotations

import numpy as np

TURN_RATE_MIN_DEG_S = 0.5
"""Default |ω| (°/s) from which a truth sample counts as in a turn."""


def turn_rate(v_prev, v, dt) -> np.ndarray:
    """(n,) turn rate ω (rad/s) between horizontal velocities ``v_prev`` and ``v``
    ((n, 2) m/s, east/north) ``dt`` (n,) s apart (module docstring). NaN where dt ≤ 0 or a
    velocity is zero."""
    a, b = np.atleast_2d(np.asarray(v_prev, float)), np.atleast_2d(np.asarray(v, float))
    dt = np.broadcast_to(np.asarray(dt, float), (len(a),))
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    dot = (a * b).sum(axis=1)
    ok = (dt > 0) & (np.hypot(*a.T) > 0) & (np.hypot(*b.T) > 0)
    out = np.full(len(a), np.nan)
    out[ok] = np.arctan2(cross[ok], dot[ok]) / dt[ok]
    return out


def in_turn(omega, min_rate_deg_s: float = TURN_RATE_MIN_DEG_S) -> np.ndarray:
    """(n,) bool: |ω| ≥ ``min_rate_deg_s`` (ω in rad/s; NaN, i.e. unknown, is not a turn)."""
    w = np.abs(np.asarray(omega, float))
    return np.nan_to_num(w, nan=0.0) >= np.radians(min_rate_deg_s)


def phase_rmse(sq_err, turning) -> dict:
    """Position RMSE (m) of squared errors ``sq_err`` (n,) m² split by ``turning`` (n,)
    bool: ``{"turn": {"samples", "rmse_m"}, "straight": {...}}`` (rmse None when empty)."""
    sq = np.asarray(sq_err, float)
    turning = np.asarray(turning, bool)
    out = {}
    for name, mask in (("turn", turning), ("straight", ~turning)):
        n = int(mask.sum())
        out[name] = {"samples": n, "rmse_m": float(np.sqrt(sq[mask].mean())) if n else None}
    return out
