"""Compiled (numba, ``cache=True``) loops of the coordinated-turn model and of its
common-format conversions, over n states of d = 5 (x, y, ψ, ω, v) or 7 (+ z, vz).

The equations are those of :mod:`fusion.models.coordinated_turn` (transition, Jacobian,
process noise Q = G diag(σ_a², σ_ω²) Gᵀ) and :mod:`fusion.models.conversions`
([Dikić] eq. 22 and its inverse, with covariances J P Jᵀ by the Jacobian of each
conversion); the docstrings there state units and frames. Here each state is one pass
of scalar arithmetic: in NumPy the same work was 20–40 array operations on arrays of a
few dozen rows (the components of one sector batch), whose per-call cost, not the
arithmetic, was the time (5–10 µs here against 40–170 µs per call at n = 50).

Inputs are float64, C-contiguous (the callers pass nothing else, so each kernel has one
compiled signature, loaded by :mod:`fusion.tracker.kernel_warmup`). The results agree
with the array formulation to rounding (the order of a few sums differs).
"""

from __future__ import annotations

import numba
import numpy as np

SMALL_OMEGA = 1e-6
"""|ω| (rad/s) below which the transition uses its ω → 0 series."""


@numba.njit(cache=True, nogil=True)
def sandwich(J: np.ndarray, P: np.ndarray) -> np.ndarray:
    """½ (A + Aᵀ) with A = J P Jᵀ, for J (n, a, b), P (n, b, b)."""
    n, a, b = J.shape
    out = np.empty((n, a, a))
    T = np.empty((a, b))
    for k in range(n):
        for i in range(a):
            for j in range(b):
                s = 0.0
                for m in range(b):
                    s += J[k, i, m] * P[k, m, j]
                T[i, j] = s
        for i in range(a):
            for j in range(a):
                s = 0.0
                for m in range(b):
                    s += T[i, m] * J[k, j, m]
                out[k, i, j] = s
        for i in range(a):
            for j in range(i + 1, a):
                h = 0.5 * (out[k, i, j] + out[k, j, i])
                out[k, i, j] = h
                out[k, j, i] = h
    return out


@numba.njit(cache=True, nogil=True)
def transition(x: np.ndarray, t: np.ndarray, vertical: bool):
    """Predicted states (n, d) and Jacobians ∂f/∂x (n, d, d) over t (n,) s."""
    n, d = x.shape
    xp = x.copy()
    J = np.zeros((n, d, d))
    for k in range(n):
        psi, w, v, tk = x[k, 2], x[k, 3], x[k, 4], t[k]
        wt = w * tk
        s0, c0 = np.sin(psi), np.cos(psi)
        s1, c1 = np.sin(psi + wt), np.cos(psi + wt)
        if abs(w) < SMALL_OMEGA:  # series in ω
            A = tk * c0 - w * tk * tk * s0 / 2
            B = tk * s0 + w * tk * tk * c0 / 2
            dA = -tk * tk * s0 / 2 - w * tk**3 * c0 / 3
            dB = tk * tk * c0 / 2 - w * tk**3 * s0 / 3
            J02, J12 = -v * tk * s0, v * tk * c0
        else:
            A = (s1 - s0) / w
            B = (c0 - c1) / w
            dA, dB = (tk * c1 - A) / w, (tk * s1 - B) / w
            J02, J12 = v * (c1 - c0) / w, v * (s1 - s0) / w
        xp[k, 0] = x[k, 0] + v * A
        xp[k, 1] = x[k, 1] + v * B
        xp[k, 2] = psi + wt
        for i in range(d):
            J[k, i, i] = 1.0
        J[k, 0, 2], J[k, 1, 2] = J02, J12
        J[k, 0, 3], J[k, 1, 3] = v * dA, v * dB
        J[k, 0, 4], J[k, 1, 4] = A, B
        J[k, 2, 3] = tk
        if vertical:
            xp[k, 5] = x[k, 5] + tk * x[k, 6]
            J[k, 5, 6] = tk
    return xp, J


@numba.njit(cache=True, nogil=True)
def process_noise(
    x: np.ndarray, t: np.ndarray, var_a: float, var_w: float, vertical: bool, q_v: float
) -> np.ndarray:
    """Q (n, d, d) = G diag(σ_a², σ_ω²) Gᵀ, G = [[T²/2 cosψ, 0], [T²/2 sinψ, 0],
    [0, T²/2], [0, T], [T, 0]]; vertical (z, vz): white acceleration q_v."""
    n, d = x.shape
    Q = np.zeros((n, d, d))
    G = np.zeros((5, 2))
    for k in range(n):
        tk = t[k]
        h = tk * tk / 2
        G[0, 0], G[1, 0], G[4, 0] = h * np.cos(x[k, 2]), h * np.sin(x[k, 2]), tk
        G[2, 1], G[3, 1] = h, tk
        for i in range(5):
            for j in range(5):
                Q[k, i, j] = G[i, 0] * var_a * G[j, 0] + G[i, 1] * var_w * G[j, 1]
        if vertical:
            Q[k, 5, 5] = q_v * tk**4 / 4
            Q[k, 5, 6] = Q[k, 6, 5] = q_v * tk**3 / 2
            Q[k, 6, 6] = q_v * tk**2
    return Q


@numba.njit(cache=True, nogil=True)
def predict(x, P, t, var_a: float, var_w: float, vertical: bool, q_v: float):
    """The EKF prediction over t (n,) s in one call: x⁻ = f(x), P⁻ = sym(J P Jᵀ + Q(x))
    with J = ∂f/∂x and Q of :func:`process_noise` at the prior states ([Dikić]
    eq. 8-9; what :func:`fusion.filters.ekf.predict` does with :func:`transition`)."""
    xp, J = transition(x, t, vertical)
    Q = process_noise(x, t, var_a, var_w, vertical, q_v)
    Pp = sandwich(J, P)
    n, d = x.shape
    for k in range(n):
        for i in range(d):
            for j in range(i + 1):
                h = 0.5 * ((Pp[k, i, j] + Q[k, i, j]) + (Pp[k, j, i] + Q[k, j, i]))
                Pp[k, i, j] = h
                Pp[k, j, i] = h
    return xp, Pp


@numba.njit(cache=True, nogil=True)
def to_common(x: np.ndarray, P: np.ndarray, vertical: bool):
    """CT → common [x, vx, ax, y, vy, ay(, z, vz, az)]: v_x = v cosψ, v_y = v sinψ,
    a_x = −ω v_y, a_y = ω v_x ([Dikić] eq. 22), covariance by the Jacobian."""
    n, d = x.shape
    dc = 9 if vertical else 6
    xc = np.zeros((n, dc))
    J = np.zeros((n, dc, d))
    for k in range(n):
        psi, w, v = x[k, 2], x[k, 3], x[k, 4]
        c, s = np.cos(psi), np.sin(psi)
        vx, vy = v * c, v * s
        xc[k, 0], xc[k, 1], xc[k, 2] = x[k, 0], vx, -w * vy
        xc[k, 3], xc[k, 4], xc[k, 5] = x[k, 1], vy, w * vx
        J[k, 0, 0] = 1.0
        J[k, 1, 2], J[k, 1, 4] = -vy, c
        J[k, 2, 2], J[k, 2, 3], J[k, 2, 4] = -w * vx, -vy, -w * s
        J[k, 3, 1] = 1.0
        J[k, 4, 2], J[k, 4, 4] = vx, s
        J[k, 5, 2], J[k, 5, 3], J[k, 5, 4] = -w * vy, vx, w * c
        if vertical:
            xc[k, 6], xc[k, 7] = x[k, 5], x[k, 6]
            J[k, 6, 5] = J[k, 7, 6] = 1.0
    return xc, sandwich(J, P)


@numba.njit(cache=True, nogil=True)
def to_cv_layout(x: np.ndarray, P: np.ndarray, vertical: bool):
    """CT → CV layout [x, vx, y, vy(, z, vz)]: the rows (x, v cosψ, y, v sinψ(, z, vz))
    of eq. 22 and of its Jacobian."""
    n, d = x.shape
    do = 6 if vertical else 4
    xo = np.empty((n, do))
    J = np.zeros((n, do, d))
    for k in range(n):
        psi, v = x[k, 2], x[k, 4]
        c, s = np.cos(psi), np.sin(psi)
        vx, vy = v * c, v * s
        xo[k, 0], xo[k, 1], xo[k, 2], xo[k, 3] = x[k, 0], vx, x[k, 1], vy
        J[k, 0, 0] = J[k, 2, 1] = 1.0
        J[k, 1, 2], J[k, 1, 4] = -vy, c
        J[k, 3, 2], J[k, 3, 4] = vx, s
        if vertical:
            xo[k, 4], xo[k, 5] = x[k, 5], x[k, 6]
            J[k, 4, 5] = J[k, 5, 6] = 1.0
    return xo, sandwich(J, P)


@numba.njit(cache=True, nogil=True)
def from_common(
    xc: np.ndarray, Pc: np.ndarray, vertical: bool, min_speed: float, significance: float
):
    """Common → CT: ψ = atan2(v_y, v_x), v = |v|, ω = (v_x a_y − v_y a_x)/v², covariance
    by the Jacobian; where v² < significance² · ½(P_vxvx + P_vyvy) course and turn rate
    are undefined: σ_ψ = π, σ_ω² = ½(P_axax + P_ayay) / max(½(P_vxvx + P_vyvy), 1),
    σ_v² = v² + ½(P_vxvx + P_vyvy), ω = 0 and no correlations of ψ, ω, v."""
    n, dc = xc.shape
    d = 7 if vertical else 5
    x = np.zeros((n, d))
    J = np.zeros((n, d, dc))
    speed2 = np.empty(n)
    for k in range(n):
        vx, ax, vy, ay = xc[k, 1], xc[k, 2], xc[k, 4], xc[k, 5]
        v2 = max(vx * vx + vy * vy, min_speed * min_speed)
        speed2[k] = v2
        v = np.sqrt(v2)
        cross = vx * ay - vy * ax
        x[k, 0], x[k, 1] = xc[k, 0], xc[k, 3]
        x[k, 2] = np.arctan2(vy, vx)
        x[k, 3] = cross / v2
        x[k, 4] = v
        J[k, 0, 0] = J[k, 1, 3] = 1.0
        J[k, 2, 1], J[k, 2, 4] = -vy / v2, vx / v2
        J[k, 3, 1] = ay / v2 - 2 * vx * cross / v2**2
        J[k, 3, 4] = -ax / v2 - 2 * vy * cross / v2**2
        J[k, 3, 2], J[k, 3, 5] = -vy / v2, vx / v2
        J[k, 4, 1], J[k, 4, 4] = vx / v, vy / v
        if vertical:
            x[k, 5], x[k, 6] = xc[k, 6], xc[k, 7]
            J[k, 5, 6] = J[k, 6, 7] = 1.0
    P = sandwich(J, Pc)
    for k in range(n):
        var_v = 0.5 * (Pc[k, 1, 1] + Pc[k, 4, 4])
        v2 = speed2[k]
        if v2 < significance * significance * var_v:
            P[k, 2:5, :] = 0.0
            P[k, :, 2:5] = 0.0
            P[k, 2, 2] = np.pi**2
            P[k, 3, 3] = 0.5 * (Pc[k, 2, 2] + Pc[k, 5, 5]) / max(var_v, 1.0)
            P[k, 4, 4] = v2 + var_v
            x[k, 3] = 0.0
    return x, P
