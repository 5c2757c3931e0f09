"""Existence gain of one IPDA update under the non-parametric clutter estimate (2.35-2.41)
against a closed form, for the gate-ellipse V_k and a larger validation volume.

Many isolated tracks with a known prediction get at most their own plot, drawn from the
predicted measurement density (a consistent filter). With m = 1, m̂ = 1 − P_D P_G ψ_{k|k−1}
and ρ̂ = m̂/V, Λ_hit = 1 − a + a V N(ν; 0, S)/(P_G m̂) (a = P_D P_G); the expected change of
logit ψ is integrated here over the χ²₂ density of d² with scipy (an independent reference,
not the tracker's code).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.special import logit
from scipy.stats import chi2
from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig

G = float(chi2.ppf(0.99, 2))
R = 25.0 * np.eye(2)
P0_AXIS = np.array([[25.0, 25.0], [25.0, 50.0]])  # two-point P_{2|2}, T = 1 s (3.27)
Q_AXIS = 0.75 * np.array([[0.25, 0.5], [0.5, 1.0]])
F_AXIS = np.array([[1.0, 1.0], [0.0, 1.0]])


def predicted_s() -> np.ndarray:
    pp = F_AXIS @ P0_AXIS @ F_AXIS.T + Q_AXIS
    return pp[0, 0] * np.eye(2) + R


def closed_form_gain(
    psi0: float, p_d: float, volume: float, S: np.ndarray, rho: float | None = None
) -> float:
    """E[logit ψ_{k|k} − logit ψ_{k−1|k−1}] for one scan (MC1 Δ11 = 0.98); ``rho``: a
    known clutter density instead of the estimate m̂/V."""
    p_g = chi2.cdf(G, 2)
    a = p_d * p_g
    psi_pred = 0.98 * psi0
    rho = (1.0 - a * psi_pred) / volume if rho is None else rho
    norm = 1.0 / (2.0 * np.pi * np.sqrt(np.linalg.det(S)))

    def integrand(x: float) -> float:
        lam = 1.0 - a + a * norm * np.exp(-x / 2.0) / (p_g * rho)
        return chi2.pdf(x, 2) * np.log(lam)

    hit = p_d * quad(integrand, 0.0, G)[0]
    return hit + (1.0 - a) * np.log(1.0 - a) + logit(psi_pred) - logit(psi0)


def simulated_gain(
    psi0: float, p_d: float, clutter_volume: float | None, n: int = 1500, rho: float = 0.0
):
    cfg = TrackerConfig(
        tracker="ipda",
        motion="cv",
        q=0.75,
        psi_init=psi0,
        tau_terminate=1e-9,
        initiation="none",
        clutter="known" if rho else "estimated",
        clutter_volume=clutter_volume,
        delta11=0.98,
        delta21=0.0,
    )
    trk = Tracker(cfg)
    P0 = np.zeros((4, 4))
    P0[0::2, 0::2] = P0_AXIS[0, 0] * np.eye(2)
    P0[0::2, 1::2] = P0[1::2, 0::2] = P0_AXIS[0, 1] * np.eye(2)
    P0[1::2, 1::2] = P0_AXIS[1, 1] * np.eye(2)
    centres = np.column_stack([1e4 * np.arange(n), np.zeros(n)])
    for c in centres:
        trk.add_track(np.array([c[0], 0.0, c[1], 0.0]), P0, 0)
    rng = np.random.default_rng(11)
    S = predicted_s()
    det = rng.random(n) < p_d
    z = centres[det] + rng.multivariate_normal(np.zeros(2), S, size=int(det.sum()))
    out = trk.step(MeasurementBatch(1_000_000_000, "r", z, R, p_d, clutter_density=rho))
    assert len(out) == n
    gain = logit(out.existence) - logit(psi0)
    return gain.mean(), gain.std(ddof=1) / np.sqrt(n)


@pytest.mark.parametrize(
    ("psi0", "p_d", "kappa"),
    [(0.01, 0.8, None), (0.3, 0.6, None), (0.9, 0.8, None), (0.01, 0.8, 5.0), (0.01, 0.6, 5.0)],
)
def test_one_scan_gain_matches_closed_form(psi0, p_d, kappa):
    S = predicted_s()
    v_gate = np.pi * G * np.sqrt(np.linalg.det(S))
    volume = v_gate if kappa is None else kappa * v_gate
    mean, se = simulated_gain(psi0, p_d, None if kappa is None else volume)
    expected = closed_form_gain(psi0, p_d, volume, S)
    assert abs(mean - expected) < 4.0 * se + 1e-3, (mean, se, expected)


@pytest.mark.parametrize(("psi0", "rho"), [(0.001, 1e-5), (0.01, 2e-4)])
def test_one_scan_gain_with_a_known_density_matches_closed_form(psi0, rho):
    """The reading that reproduces the single-target table: ρ known (thesis-stt's weak
    and strong regions) at P_D = 0.6, first update after the two-point start. Gain
    > 1 nat per scan in the weak region, against < 0 under the estimate (next test)."""
    S = predicted_s()
    mean, se = simulated_gain(psi0, 0.6, None, rho=rho)
    expected = closed_form_gain(psi0, 0.6, 0.0, S, rho=rho)
    assert abs(mean - expected) < 4.0 * se + 1e-3, (mean, se, expected)
    if rho == 1e-5:
        assert expected > 1.0


def test_stated_model_loses_existence_at_low_detection():
    """P_D = 0.6 and V = gate of S: the expected gain of a true track is negative below
    ψ ≈ 0.45 (the source's single-target P_D), positive with a 5× larger V."""
    S = predicted_s()
    v_gate = np.pi * G * np.sqrt(np.linalg.det(S))
    assert closed_form_gain(0.05, 0.6, v_gate, S) < -0.05
    assert closed_form_gain(0.05, 0.6, 5.0 * v_gate, S) > 0.3


def test_plot_count_uses_the_track_level_gate_of_v():
    """m̂ (2.35) counts the plots in the same track-level gate whose volume V_k divides it.

    A two-component ITS track: a strong tight component and a weak wide one. A second
    target's plot lies in the wide component's gate but outside the ellipse of the
    moment-matched S̄; only the own plot is in V_k, so m = 1 (the union of the component
    gates would give m = 2 and double ρ̂). Closed form: ρ̂ = (1 − a ψ_{k|k−1})/V_k,
    p_i = Σ_{c gates i} ξ^c N(z_i; ŷ, S^c)/P_G, Λ (2.39) and ψ (2.41)."""
    from skyfuse.fusion.tracker.components import Mixture

    p_d, psi0 = 0.8, 0.2
    trk = Tracker(
        TrackerConfig(
            tracker="its", depth=1, q=0.75, psi_init=psi0, initiation="none", motion="cv",
            clutter="estimated", delta11=0.98, delta21=0.0,
        )
    )  # fmt: skip
    x = np.array([0.0, 10.0, 0.0, 0.0])
    P_small, P_wide = np.diag([10.0, 1.0, 10.0, 1.0]), np.diag([5000.0, 1.0, 5000.0, 1.0])
    trk.add_track(x, P_small, 0)
    w = np.array([0.99, 0.01])
    trk.density.mix = Mixture(
        np.zeros(2, np.int64), w, np.stack([x, x]), np.stack([P_small, P_wide]),
        np.zeros((2, 1), np.int64),
    )  # fmt: skip
    F = np.kron(np.eye(2), F_AXIS)
    Q = np.kron(np.eye(2), Q_AXIS)
    H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    y = H @ F @ x
    S = [H @ (F @ P @ F.T + Q) @ H.T + R for P in (P_small, P_wide)]
    S_bar = w[0] * S[0] + w[1] * S[1]
    z = y + np.array([[3.0, -4.0], [100.0, 0.0]])
    inside = [float((zi - y) @ np.linalg.solve(S_bar, zi - y)) < G for zi in z]
    assert inside == [True, False]
    p_g = chi2.cdf(G, 2)

    def gauss(nu, s):
        return np.exp(-0.5 * nu @ np.linalg.solve(s, nu)) / (2 * np.pi * np.sqrt(np.linalg.det(s)))

    p = [
        sum(
            w[c] * gauss(zi - y, S[c])
            for c in range(2)
            if (zi - y) @ np.linalg.solve(S[c], zi - y) < G
        )
        / p_g
        for zi in z
    ]
    a = p_d * p_g
    psi_pred = 0.98 * psi0
    rho = (1.0 - a * psi_pred) / (np.pi * G * np.sqrt(np.linalg.det(S_bar)))
    lam = 1.0 - a + a * (p[0] + p[1]) / rho
    expected = lam * psi_pred / (1.0 - (1.0 - lam) * psi_pred)
    out = trk.step(MeasurementBatch(1_000_000_000, "r", z, R, p_d))
    assert out.existence[0] == pytest.approx(expected, rel=1e-9)
