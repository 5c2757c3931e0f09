"""Simulated radar biases: the plots of a biased radar, compared with the
truth geometry (pymap3d), show the configured offsets — statistical tests at 5 σ of the
sample mean — and the truth messages carry the biases."""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest
from skyfuse.fusion.sim import Simulator, build_scenario


def _residuals(params: dict, *, shift_time: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(range residual m, azimuth residual rad, true range m) of every target plot of
    crossing-4g, the truth evaluated at the reported time minus the time bias when
    ``shift_time`` (the true detection time) or at the reported time."""
    sc = build_scenario("crossing-4g", seed=4, p_detection=1.0, **params)
    bias_t = params.get("radar.bias_time_ms", 0.0) * 1e-3
    s = sc.sites[0]
    dr, da, rr = [], [], []
    for scan in Simulator(sc).scans():
        tgt = scan.target_id >= 0
        t = (scan.time[tgt] - sc.start_time) * 1e-9 - (bias_t if shift_time else 0.0)
        index = np.searchsorted(sc.targets.target_id, scan.target_id[tgt])
        lat, lon, alt = sc.geodetic(index, t)
        az, _, r = pymap3d.geodetic2aer(lat, lon, alt, s.lat, s.lon, s.alt, deg=True)
        az = np.radians(az)
        dr.append(scan.range[tgt] - r)
        da.append((scan.azimuth[tgt] - az + math.pi) % (2 * math.pi) - math.pi)
        rr.append(r)
    return np.concatenate(dr), np.concatenate(da), np.concatenate(rr)


def _consistent(sample: np.ndarray, mean: float, k: float = 5.0) -> bool:
    return abs(sample.mean() - mean) < k * sample.std(ddof=1) / math.sqrt(sample.size)


def test_unbiased_radar_residuals_are_zero_mean():
    dr, da, _ = _residuals({}, shift_time=True)
    assert dr.size > 30
    assert _consistent(dr, 0.0) and _consistent(da, 0.0)


def test_range_and_azimuth_offsets_appear_in_the_plots():
    params = {"radar.bias_azimuth_deg": 0.4, "radar.bias_range_m": 150.0}
    dr, da, _ = _residuals(params, shift_time=True)
    assert _consistent(dr, 150.0) and _consistent(da, math.radians(0.4))
    assert not _consistent(dr, 0.0) and not _consistent(da, 0.0)


def test_range_gain_scales_with_range():
    gain = 10_000e-6
    dr, _, r = _residuals({"radar.bias_range_gain_ppm": 10_000.0}, shift_time=True)
    # least squares slope of the range residual on the true range
    coef, cov = np.polyfit(r, dr, 1, cov=True)
    se = math.sqrt(cov[0, 0])
    assert abs(coef[0] - gain) < 5 * se < 0.5 * gain
    assert _consistent(dr - gain * r, 0.0)


def test_time_offset_shifts_the_time_stamps():
    params = {"radar.bias_time_ms": 1000.0}  # the targets fly 311 m/s towards the radar
    dr, da, _ = _residuals(params, shift_time=True)
    assert _consistent(dr, 0.0) and _consistent(da, 0.0)
    dr_naive, _, _ = _residuals(params, shift_time=False)
    # at the reported time the targets are already up to 311 m closer (radial part of
    # 311 m/s; less after the turns) than the plots say
    assert dr_naive.mean() > 150.0 and not _consistent(dr_naive, 0.0)


def test_truth_records_the_biases_and_params_validate():
    sc = build_scenario("regional", duration=10.0, **{"LYVR.bias_range_m": 150.0})
    truth = Simulator(sc).truth_message(sc.start_time)
    assert [(b.radar_id, b.range) for b in truth.radar_bias] == [("LYVR", 150.0)]
    assert sc.params["LYVR.bias_range_m"] == 150.0
    assert build_scenario("regional", duration=10.0).sensors[1].bias.is_zero
    with pytest.raises(ValueError, match=r"LYVR\.bias_azimuth_deg"):
        build_scenario("regional", duration=10.0, **{"LYVR.bias_azimuth_deg": 45.0})
    with pytest.raises(ValueError, match="unknown parameter"):
        build_scenario("regional", duration=10.0, **{"XX.bias_range_m": 1.0})
