"""Antenna scan period estimated from plot times and azimuths (no CAT034 needed).

A rotating antenna sees a plot at azimuth θ only when the beam points there, so
θ_k ≈ φ0 + 2π t_k / T (mod 2π) for every plot k, whatever the targets. For a trial
frequency f the phases ψ_k = θ_k − 2π f t_k are all equal when f = 1/T, so the
mean resultant length

    R(f) = | (1/n) Σ_k exp(i ψ_k) |                (Rayleigh statistic)

peaks at f = 1/T (R = 1 for noiseless plots) and is ≈ 1/√n elsewhere. Sub- and
super-harmonics do not peak: ψ_k then still drifts with t_k. The search runs on a
coarse frequency grid over a short time window, then refines on all plots with a
grid step of 1/(8 × span), which resolves T to a small fraction of a percent.
"""

from __future__ import annotations

import numpy as np

MIN_PERIOD_S = 0.5
MAX_PERIOD_S = 30.0


def _resultant(t: np.ndarray, az: np.ndarray, freqs: np.ndarray, chunk: int = 256) -> np.ndarray:
    out = np.empty(freqs.size)
    e = np.exp(1j * az)
    for i in range(0, freqs.size, chunk):
        f = freqs[i : i + chunk]
        phase = np.exp(-2j * np.pi * np.outer(f, t))  # (nf, n)
        out[i : i + chunk] = np.abs(phase @ e) / t.size
    return out


def estimate_scan_period(
    times_s: np.ndarray,
    azimuths_rad: np.ndarray,
    *,
    min_period: float = MIN_PERIOD_S,
    max_period: float = MAX_PERIOD_S,
    max_plots: int = 3000,
) -> tuple[float, float] | None:
    """Estimate the scan period (s) of a clockwise-rotating radar from its plots.

    ``times_s``: plot times in seconds (any origin); ``azimuths_rad``: azimuths, rad
    clockwise from north. Returns ``(period_s, R)`` where ``R`` ∈ [0, 1] is the peak
    mean resultant length (near 1 = clean fit), or ``None`` with fewer than 8 plots,
    a time span shorter than two maximum periods' worth of plots (span < 2 ×
    ``min_period``), or no peak clearly above the noise level (R < 4/√n)."""
    t = np.asarray(times_s, dtype=np.float64)
    az = np.asarray(azimuths_rad, dtype=np.float64)
    ok = np.isfinite(t) & np.isfinite(az)
    t, az = t[ok], az[ok]
    if t.size < 8:
        return None
    order = np.argsort(t, kind="stable")
    t, az = t[order] - t[order][0], az[order]
    span_all = float(t[-1])
    if span_all < 2.0 * min_period:
        return None
    # Coarse search: the first plots, up to 1000 and ~10 maximum periods.
    head = (t <= 10.0 * max_period) & (np.arange(t.size) < min(max_plots, 1000))
    th, ah = t[head], az[head]
    span = max(float(th[-1]), 1e-9)
    step = 1.0 / (8.0 * span)
    freqs = np.arange(1.0 / max_period, 1.0 / min_period + step, step)
    r = _resultant(th, ah, freqs)
    k = int(np.argmax(r))
    f0, r0 = float(freqs[k]), float(r[k])
    if r0 < 4.0 / np.sqrt(th.size):
        return None
    # Refine on all plots (thinned to max_plots spread over the whole span).
    if t.size > max_plots:
        pick = np.linspace(0, t.size - 1, max_plots).round().astype(int)
        t, az = t[pick], az[pick]
    fine_step = 1.0 / (8.0 * max(span_all, 1e-9))
    lo, hi = f0 - 2.0 * step, f0 + 2.0 * step
    while True:
        fine = np.arange(lo, hi + fine_step, fine_step)
        if fine.size <= 20_000:
            break
        fine_step *= 2.0
    rf = _resultant(t, az, fine)
    j = int(np.argmax(rf))
    # Parabolic interpolation of the peak between grid points.
    f_best = float(fine[j])
    if 0 < j < fine.size - 1:
        y0, y1, y2 = rf[j - 1], rf[j], rf[j + 1]
        denom = y0 - 2.0 * y1 + y2
        if denom < 0:
            f_best += 0.5 * (y0 - y2) / denom * fine_step
    return float(1.0 / f_best), float(rf[j])
