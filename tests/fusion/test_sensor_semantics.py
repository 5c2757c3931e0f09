"""What the existence trackers assume of each sensor kind (fusion.tracker.report_clock,
measurements, coverage_polygon): checked against closed forms — the Markov chain alone
(ψ Δ11^t: no evidence either way) and the IPDA miss update ψ' = (1 − P_D P_G) ψ /
(1 − P_D P_G ψ) ([thesis] 2.41) — and against matplotlib's polygon test.

* A report-based sensor (ADS-B, multilateration) that never reported a track leaves its
  existence to the chain: a non-cooperative target is not eroded by ADS-B batches.
* A track the sensor did report is eroded by its silence for ``report_timeout`` s, then
  no more: a cooperative track whose reports stop.
* A sweeping sensor erodes every track in its coverage; a coverage polygon and a ceiling
  limit that coverage.
* Plot timing: each track is predicted to the time of its own report in a batch.
"""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.path import Path
from scipy.special import ndtr
from scipy.stats import chi2
from skyfuse.fusion.tracker import Tracker, TrackerConfig
from skyfuse.fusion.tracker.coverage_polygon import inside, share_inside, signed_distance
from skyfuse.fusion.tracker.measurements import MeasurementBatch, SectorCoverage

S = 1_000_000_000
PD = 0.9
P_G = chi2.cdf(chi2.ppf(0.99, 2), 2)
D11 = 0.98


def _tracker() -> Tracker:
    return Tracker(TrackerConfig(motion="cv", initiation="none", max_coast=None, delta11=D11))


def _track(trk: Tracker, x, y, psi=0.99) -> int:
    P = np.diag([10.0**2, 2.0**2, 10.0**2, 2.0**2])
    return trk.add_track(np.array([x, 0.0, y, 0.0]), P, 0, psi, True)


def _batch(t_s, sensor, plots=(), times=None, **coverage) -> MeasurementBatch:
    z = np.array(plots, dtype=float).reshape(-1, 2)
    t = np.full(len(z), round(t_s * S)) if times is None else np.array(times, np.int64)
    cov = SectorCoverage(site=np.array([-50_000.0, 0.0]), max_range=1e6, time_start=round(t_s * S),
                         time_end=round(t_s * S), **coverage)  # fmt: skip
    return MeasurementBatch(round(t_s * S), sensor, z, np.eye(2) * 25.0, PD, 1e-8,
                            coverage=cov, plot_times=t)  # fmt: skip


def _psi(out, tid) -> float:
    return float(out.existence[list(out.ids).index(tid)])


def miss(psi: float) -> float:
    """[thesis] 2.41 for a full miss."""
    return (1 - PD * P_G) * psi / (1 - PD * P_G * psi)


def test_a_track_adsb_never_reported_is_not_eroded_by_adsb_batches():
    trk = _tracker()
    a = _track(trk, 0.0, 0.0)  # a non-cooperative target (an SMR's track)
    b = _track(trk, 5_000.0, 0.0)  # a cooperative one
    for k in range(1, 11):  # ten ADS-B batches reporting b only
        out = trk.step(_batch(k, "adsb", [(5_000.0, 0.0)], detection="reports"))
    assert _psi(out, a) == pytest.approx(0.99 * D11**10, rel=1e-9)  # the chain alone
    assert _psi(out, b) > 0.98
    # the same batches from a sweeping sensor: ten misses
    trk2 = _tracker()
    a2 = _track(trk2, 0.0, 0.0)
    _track(trk2, 5_000.0, 0.0)
    for k in range(1, 11):
        out2 = trk2.step(_batch(k, "radar", [(5_000.0, 0.0)]))
    assert a2 not in out2.ids or _psi(out2, a2) < 1e-3


def test_a_cooperative_track_is_eroded_when_its_reports_stop_then_left_alone():
    trk = _tracker()
    b = _track(trk, 0.0, 0.0)
    out = trk.step(_batch(1, "adsb", [(0.0, 0.0)], detection="reports", report_timeout=3.0))
    psi = _psi(out, b)
    # its reports stop: misses at t = 2, 3, 4 (within 3 s of its last report at t = 1) ...
    for k in (2, 3, 4):
        out = trk.step(_batch(k, "adsb", [], detection="reports", report_timeout=3.0))
        psi = miss(psi * D11)
        assert _psi(out, b) == pytest.approx(psi, rel=1e-9)
    # ... then the sensor says nothing about it any more: the chain alone
    for k in (5, 6, 7):
        out = trk.step(_batch(k, "adsb", [], detection="reports", report_timeout=3.0))
    assert _psi(out, b) == pytest.approx(psi * D11**3, rel=1e-9)


def test_the_report_clock_survives_a_snapshot():
    from skyfuse.fusion.tracker.tracker import tracker_from_snapshot

    trk = _tracker()
    b = _track(trk, 0.0, 0.0)
    trk.step(_batch(1, "adsb", [(0.0, 0.0)], detection="reports"))
    again = tracker_from_snapshot(trk.to_snapshot())
    assert again.reports.names == ["adsb"]
    np.testing.assert_array_equal(again.tracks.report_t, trk.tracks.report_t)
    out1 = trk.step(_batch(2, "adsb", [], detection="reports"))
    out2 = again.step(_batch(2, "adsb", [], detection="reports"))
    assert _psi(out1, b) == _psi(out2, b) < 0.99


def test_polygon_and_ceiling_limit_a_sweeping_sensors_coverage():
    square = np.array([[-1000.0, -1000.0], [1000.0, -1000.0], [1000.0, 1000.0], [-1000.0, 1000.0]])
    trk = _tracker()
    inside_id = _track(trk, 0.0, 0.0)
    outside_id = _track(trk, 3000.0, 0.0)
    high = _track(trk, 500.0, 0.0)
    trk.tracks.height[:] = [10.0, 10.0, 3000.0]
    out = trk.step(_batch(1, "smr", [], polygon=square, max_height=300.0))
    assert _psi(out, inside_id) == pytest.approx(miss(0.99 * D11), rel=1e-6)
    assert _psi(out, outside_id) == pytest.approx(0.99 * D11, rel=1e-9)
    assert _psi(out, high) == pytest.approx(0.99 * D11, rel=1e-9)


def test_polygon_inside_and_share_against_matplotlib_and_the_half_plane():
    rng = np.random.default_rng(3)
    poly = np.array([[0, 0], [4000, 500], [3000, 3000], [1500, 1200], [200, 2500]], float)
    pts = rng.uniform(-500, 4500, (2000, 2))
    assert (inside(pts, poly) == Path(poly).contains_points(pts)).all()
    # far from the vertices the boundary is a straight line: Φ(d/σ) exactly
    edge_mid = (poly[0] + poly[1]) / 2
    normal = np.array([-(poly[1] - poly[0])[1], (poly[1] - poly[0])[0]])
    normal /= np.linalg.norm(normal)  # points inside (counter-clockwise polygon)
    for d in (-30.0, 0.0, 12.0, 50.0):
        p = edge_mid + d * normal
        assert signed_distance(p[None], poly)[0] == pytest.approx(d, abs=1e-6)
        assert share_inside(p[None], np.array([20.0]), poly)[0] == pytest.approx(ndtr(d / 20))


def test_each_track_is_predicted_to_the_time_of_its_own_report():
    trk = _tracker()
    a = _track(trk, 0.0, 0.0)
    b = _track(trk, 8_000.0, 0.0)
    times = [round(1.2 * S), round(1.9 * S)]
    trk.step(_batch(2, "mlat", [(0.0, 0.0), (8_000.0, 0.0)], times=times, detection="reports",
                    timing="plots"))  # fmt: skip
    t_last = dict(zip(trk.ids.tolist(), trk.tracks.t_last.tolist()))
    assert t_last[a] == times[0] and t_last[b] == times[1]
    rows = [list(trk.ids).index(a), list(trk.ids).index(b)]
    assert trk.tracks.report_t[rows, 0].tolist() == times
