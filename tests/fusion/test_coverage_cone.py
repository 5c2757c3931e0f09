"""Cone of silence and detection share (fusion.tracker.measurements eqs. C1-C4, coverage).

References: pymap3d's geodetic→AER elevation on the WGS-84 ellipsoid (geometric, k = 1)
for (C1); the closed-form IPDA existence update ψ' = ψ_pred when P_D = 0 ([thesis] (2.41))
and ψ' = (1 − P_D P_G) ψ / (1 − P_D P_G ψ) for a full miss.
"""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest
from scipy.stats import chi2
from skyfuse.fusion.tracker import Tracker, TrackerConfig
from skyfuse.fusion.tracker.measurements import (
    MeasurementBatch,
    SectorCoverage,
    elevation_angle,
)

LAT, LON, H0 = 41.3, 2.1, 27.0


@pytest.mark.parametrize("rho,h", [(5_000.0, 3_000.0), (17_000.0, 11_000.0), (80_000.0, 9_000.0)])
def test_elevation_matches_pymap3d(rho, h):
    # a point at ground distance rho due north (on the mean sphere) and height h
    lat = LAT + np.degrees(rho / 6_371_008.8)
    _, el, _ = pymap3d.geodetic2aer(lat, LON, h, LAT, LON, H0)
    e = np.degrees(elevation_angle(np.array([rho]), np.array([h]), H0, 6_371_008.8))[0]
    assert abs(e - el) < 0.05  # ellipsoid vs sphere and the meridian radius


def test_in_cone_is_the_elevation_limit():
    cov = SectorCoverage(site=np.zeros(2), max_elevation=np.radians(45.0), site_height=0.0)
    # at h = 10 km the 45° edge is at ground range ≈ 10 km (curvature: a few metres)
    pos = np.array([[0.0, 9_900.0], [0.0, 10_100.0], [0.0, 100.0]])
    got = cov.in_cone(pos, np.array([10_000.0, 10_000.0, np.nan]))
    assert got.tolist() == [True, False, False]


def _tracker_with_overflight(max_elevation):
    cfg = TrackerConfig(motion="cv", initiation="none", max_coast=60.0)
    trk = Tracker(cfg)
    # aircraft at 11 km height flying north at 100 m/s, 1 km east of the radar
    x = np.array([1_000.0, 0.0, -2_000.0, 100.0])
    tid = trk.add_track(x, np.diag([50.0**2, 10.0**2, 50.0**2, 10.0**2]), 0, 0.99, True)
    trk.tracks.height[:] = 11_000.0
    cov = SectorCoverage(site=np.zeros(2), max_elevation=max_elevation, site_height=0.0)
    out = None
    for k in range(1, 21):  # 20 empty 4 s scans: the track stays within 6 km of the radar
        b = MeasurementBatch(k * 4_000_000_000, "R", np.zeros((0, 2)), np.eye(2), 0.9,
                             1e-9, coverage=cov)  # fmt: skip
        out = trk.step(b)
    return tid, out


def test_no_erosion_and_no_termination_in_the_cone():
    tid, out = _tracker_with_overflight(np.radians(45.0))
    assert tid in out.ids  # 80 s without plots, max_coast 60 s: coasting in a known gap
    psi = out.existence[list(out.ids).index(tid)]
    # blind in every batch: the Markov chain (Δ11 = 0.98 per second) is held in the cone,
    # so ψ stays at its value on entry (it would be 0.99 · 0.98^80 ≈ 0.20 otherwise)
    assert psi == pytest.approx(0.99, rel=1e-12)


def test_existence_resumes_its_chain_after_the_cone():
    tid, out = _tracker_with_overflight(np.radians(45.0))
    # predicted 10 s past the last blind batch: only those 10 s of the chain act
    later = out.prediction
    later.time_ns += 10_000_000_000
    psi = later.rows(np.array([list(out.ids).index(tid)]))[2][0]
    assert psi == pytest.approx(0.99 * 0.98**10, rel=1e-9)


def test_misses_erode_without_a_cone():
    tid, out = _tracker_with_overflight(None)
    assert tid not in out.ids  # 20 misses at P_D = 0.9: existence far below τ_t


def test_one_miss_at_full_share_matches_closed_form():
    cfg = TrackerConfig(motion="cv", initiation="none", max_coast=None)
    trk = Tracker(cfg)
    trk.add_track(np.array([0.0, 0.0, 50_000.0, 0.0]), np.eye(4), 0, 0.9, True)
    cov = SectorCoverage(site=np.zeros(2), max_elevation=np.radians(45.0))
    out = trk.step(MeasurementBatch(1, "R", np.zeros((0, 2)), np.eye(2), 0.9, 1e-9,
                                    coverage=cov))  # fmt: skip
    pdpg = 0.9 * chi2.cdf(chi2.ppf(0.99, 2), 2)
    assert out.existence[0] == pytest.approx((1 - pdpg) * 0.9 / (1 - pdpg * 0.9), rel=1e-6)
