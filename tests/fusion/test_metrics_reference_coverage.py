"""The input bound and the assessed area of the reference scores
(fusion/metrics/reference_coverage.py): hand-counted windows, the gate boundary, Mode-S
addresses telling aircraft apart, an empty input, a brute-force implementation with
loops on random scenes, the polygon test against matplotlib's, the minimum surface
speed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reference_brute_support import interp, presence_segments
from skyfuse.fusion.metrics.reference_association import ReferenceSamples, TrackUpdates
from skyfuse.fusion.metrics.reference_coverage import InputPlots, ScoreArea
from skyfuse.fusion.metrics.reference_scores import ReferenceScoreConfig, score_against_reference

T0 = 1_700_000_000 * 10**9
S = 10**9


def taxiing(key=0xABC, n=21, v=10.0, y=0.0, ground=True, t_step=1.0):
    """One aircraft on the ground at x = v t, y, samples every t_step s from T0."""
    t = np.arange(n) * t_step
    return ReferenceSamples(
        T0 + (t * S).astype(np.int64), np.full(n, key), v * t, np.full(n, y), np.full(n, ground)
    )


def plots_at(t, dx, dy=None, v=10.0, mode_s=None, window_t=None):
    """Plots at times t (s) placed dx, dy m from the aircraft of :func:`taxiing`."""
    t = np.asarray(t, float)
    dy = np.zeros_like(t) if dy is None else np.asarray(dy, float)
    tw = None if window_t is None else T0 + (np.asarray(window_t) * S).astype(np.int64)
    return InputPlots(T0 + (t * S).astype(np.int64), v * t + dx, dy, tw, mode_s)


def updates_at(t, v=10.0):
    t = np.asarray(t, float)
    return TrackUpdates(T0 + (t * S).astype(np.int64), np.zeros(len(t), np.int64), v * t, 0 * t)


def test_hand_counted_windows_and_the_gate_boundary():
    ref = taxiing()  # 0..20 s on the ground: 20 windows of 1 s
    # plots in windows 0..9 within the gate; window 10: exactly 50 m (in: d <= gate);
    # window 11: 50.5 m (out); window 12: 50 m across the track (in); none after
    t = [0.5, 1.2, 1.7, 2.5, 3.5, 4.5, 5.5, 6.5, 7.5, 8.5, 10.5, 11.5, 12.5]
    dx = [0, 5, -5, 0, 10, 0, 0, 0, 0, 0, 50.0, 50.5, 0]
    dy = [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 50.0]
    plots = plots_at(t, dx, dy)
    # the track updated windows 0..4 and 15..19
    upd = updates_at([0.5, 1.5, 2.5, 3.5, 4.5, 15.5, 16.5, 17.5, 18.5, 19.5])
    s = score_against_reference(upd, ref, plots=plots)
    c = s.surface.coverage
    assert (c.windows, c.updated) == (20, 10)
    # reported: windows 0..8, 10, 12 = 11 (9 has none: 8.5 is window 8)
    assert c.input == 11
    assert c.input_updated == 5  # windows 0..4
    assert c.updated_without_input == 5  # 15..19
    assert c.input_bound == pytest.approx(11 / 20)
    assert c.where_input == pytest.approx(5 / 11)
    assert s.airborne.coverage.input == 0
    a = s.per_aircraft
    assert (a.input_surface[0], a.input_updated_surface[0]) == (11, 5)


def test_window_time_is_the_batch_time():
    ref = taxiing()
    # a plot measured at 3.9 s reaches the tracker in the batch of 4.2 s: window 4
    plots = plots_at([3.9], [0.0], window_t=[4.2])
    s = score_against_reference(updates_at([4.2]), ref, plots=plots)
    c = s.surface.coverage
    assert (c.input, c.input_updated, c.updated_without_input) == (1, 1, 0)


def test_mode_s_tells_aircraft_apart_in_the_input_bound_only():
    a = taxiing(key=0xA)
    b = taxiing(key=0xB, y=30.0)  # 30 m beside A, inside the 50 m gate of both
    ref = ReferenceSamples(*(np.r_[getattr(a, k), getattr(b, k)] for k in
                             ("time_ns", "key", "x", "y", "ground")))  # fmt: skip
    # plots on A's side (y = 5) in windows 0..9; the first five show B's address
    plots = plots_at(np.arange(10) + 0.5, np.zeros(10), np.full(10, 5.0),
                     mode_s=np.r_[np.full(5, 0xB), np.full(5, -1)])  # fmt: skip
    s = score_against_reference(updates_at([]), ref, plots=plots)
    keys = list(s.aircraft_keys)
    per = dict(zip(keys, s.per_aircraft.input_surface.tolist()))
    assert per == {0xA: 5, 0xB: 5}  # without addresses: nearest is A (5 m vs 25 m)
    # an address no reference aircraft has: no aircraft's plot
    plots = plots_at([0.5], [0.0], mode_s=np.array([0xC]))
    assert score_against_reference(updates_at([]), ref, plots=plots).surface.coverage.input == 0
    # the track updates themselves never use identity: an update on A showing B's address
    u = TrackUpdates(T0 + np.array([S // 2]), np.zeros(1, np.int64), np.zeros(1),
                     np.full(1, 5.0), mode_s=np.array([0xB]))  # fmt: skip
    s = score_against_reference(u, ref)
    assert s.aircraft_keys[s.association.assigned[0]] == 0xA


def test_empty_input_and_no_input():
    ref = taxiing()
    upd = updates_at([0.5, 1.5])
    s = score_against_reference(upd, ref, plots=InputPlots.concat([]))
    c = s.surface.coverage
    assert (c.input, c.input_updated, c.updated_without_input) == (0, 0, 2)
    assert c.input_bound == 0.0 and math.isnan(c.where_input)
    s = score_against_reference(upd, ref)  # no input given: no bound
    assert s.surface.coverage.input is None and s.surface.coverage.input_bound is None
    assert s.per_aircraft.input_surface is None


def test_max_range_applies_to_the_plots():
    ref = taxiing()  # x from 0 to 200 m
    plots = plots_at([0.5, 15.5], [0.0, 0.0])  # at 5 m and 155 m from the origin
    cfg = ReferenceScoreConfig(max_range_m=100.0)
    s = score_against_reference(updates_at([]), ref, cfg, plots=plots)
    assert s.surface.coverage.input == 1


# ---- brute force ----------------------------------------------------------------------


def scene(seed: int):
    """Random aircraft (gaps, phase changes, 0.4-9 s between samples) and plots near them
    (some with an address, some beyond the gate, some of nothing)."""
    rng = np.random.default_rng(seed)
    ref, plots = [], []
    n_ac = int(rng.integers(1, 4))
    for a in range(n_ac):
        p0, v = rng.uniform(-300, 300, 2), rng.uniform(-30, 30, 2)
        t = np.cumsum(rng.choice([0.4, 1.0, 2.0, 5.0, 9.0], 90, p=[0.3, 0.3, 0.3, 0.07, 0.03]))
        t = t[t < 60]
        switch = rng.uniform(0, 70)
        g = (t < switch) if rng.random() < 0.5 else (t >= switch)
        ref += [(ti, 0x100 + a, *(p0 + v * ti), gi) for ti, gi in zip(t, g)]
        for ti in np.sort(rng.uniform(0, 60, int(rng.integers(0, 80)))):
            off = rng.normal(0, rng.choice([10.0, 60.0, 250.0]), 2)
            ms = 0x100 + int(rng.integers(0, n_ac + 1)) if rng.random() < 0.3 else -1
            plots.append((ti, *(p0 + v * ti + off), ti + rng.uniform(0, 1.2), ms))
    ref = np.array(ref, dtype=float)
    # times rounded to the ns (truncating 46.999999999999 s would leave a segment 1 ns short
    # of a whole window, where the scorer's and this file's float tolerances differ)
    r = ReferenceSamples(T0 + np.round(ref[:, 0] * S).astype(np.int64), ref[:, 1].astype(np.int64),
                         ref[:, 2], ref[:, 3], ref[:, 4].astype(bool))  # fmt: skip
    p = np.array(plots, dtype=float).reshape(-1, 5)
    t_plot, t_window = (T0 + np.round(p[:, c] * S).astype(np.int64) for c in (0, 3))
    ip = InputPlots(t_plot, p[:, 1], p[:, 2], t_window, p[:, 4].astype(np.int64))
    return r, ip


def brute_input_windows(r: ReferenceSamples, p: InputPlots, cfg):
    """{aircraft: {ground: [windows, reported]}} with loops."""
    epoch = min(r.time_ns.min(), p.time_ns.min()) if len(p) else r.time_ns.min()
    ac = {}
    for i in range(len(r)):
        ac.setdefault(int(r.key[i]), []).append(
            ((r.time_ns[i] - epoch) * 1e-9, r.x[i], r.y[i], bool(r.ground[i]))
        )
    ac = {k: sorted(v) for k, v in ac.items() if len(v) >= cfg.min_reference_samples}
    label = []
    for i in range(len(p)):
        t = (p.time_ns[i] - epoch) * 1e-9
        best, best_d = None, math.inf
        for k, smp in ac.items():
            q = interp(smp, t, cfg.max_reference_gap_s)
            if q is None or (p.mode_s[i] >= 0 and p.mode_s[i] != k):
                continue
            d = math.hypot(p.x[i] - q[0], p.y[i] - q[1])
            if d <= (cfg.gate_surface_m if q[2] else cfg.gate_airborne_m) and d < best_d:
                best, best_d = k, d
        label.append(best)
    out = {}
    for k, smp in ac.items():
        segs = presence_segments(smp, cfg.max_reference_gap_s)
        counts = {True: [0, 0], False: [0, 0]}
        for seg in segs:
            g = seg[0][3]
            width = cfg.surface_window_s if g else cfg.airborne_window_s
            j = 0
            while seg[0][0] + (j + 1) * width <= seg[-1][0] + 1e-9 * width:
                lo, hi = seg[0][0] + j * width, seg[0][0] + (j + 1) * width
                hit = any(label[i] == k and lo <= (p.window_time_ns[i] - epoch) * 1e-9 < hi
                          for i in range(len(p)))  # fmt: skip
                counts[g][0] += 1
                counts[g][1] += hit
                j += 1
        out[k] = counts
    return out


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_input_windows_equal_a_brute_force_implementation(seed):
    r, p = scene(seed)
    cfg = ReferenceScoreConfig(min_reference_samples=5)
    # one update at the earliest plot: the scorer's epoch is the brute force's
    first = p.take(np.argsort(p.time_ns)[:1])
    u = TrackUpdates(first.time_ns, np.zeros(len(first), np.int64), first.x, first.y)
    s = score_against_reference(u, r, cfg, plots=p)
    want = brute_input_windows(r, p, cfg)
    assert sorted(want) == list(s.aircraft_keys)
    a = s.per_aircraft
    for i, k in enumerate(s.aircraft_keys):
        assert (a.windows_surface[i], a.input_surface[i]) == tuple(want[k][True])
        assert (a.windows_airborne[i], a.input_airborne[i]) == tuple(want[k][False])
    assert s.surface.coverage.input == sum(w[True][1] for w in want.values())


# ---- the assessed area ------------------------------------------------------------------


def test_polygon_test_against_matplotlib():
    from matplotlib.path import Path

    rng = np.random.default_rng(3)
    # a concave (L-shaped) polygon and a triangle
    ell = np.array([[0, 0], [400, 0], [400, 100], [100, 100], [100, 300], [0, 300]], float)
    tri = np.array([[500, 500], [700, 500], [600, 650]], float)
    area = ScoreArea((ell, tri))
    x, y = rng.uniform(-50, 750, 4000), rng.uniform(-50, 700, 4000)
    pts = np.column_stack([x, y])
    want = Path(ell).contains_points(pts) | Path(tri).contains_points(pts)
    assert (area.contains(x, y) == want).all()
    # by hand: inside the L's foot and leg, outside its notch
    assert area.contains(np.array([350.0, 50.0, 300.0]), np.array([50.0, 250.0, 250.0])).tolist() \
        == [True, True, False]  # fmt: skip
    assert ScoreArea().contains(x[:3], y[:3]).all()  # no polygon: everywhere
    with pytest.raises(ValueError, match="polygon 0"):
        ScoreArea((np.zeros((2, 2)),))


def test_area_restricts_windows_and_errors_beside_the_whole():
    ref = taxiing()  # x = 10 t, 0..200 m
    upd = TrackUpdates(T0 + ((np.arange(20) + 0.5) * S).astype(np.int64),
                       np.zeros(20, np.int64), 10 * (np.arange(20) + 0.5) + 3.0,
                       np.zeros(20))  # fmt: skip
    box = np.array([[-10, -10], [100.0, -10], [100, 10], [-10, 10]])  # x < 100: 0..10 s
    s = score_against_reference(upd, ref, area_polygons=[box], plots=plots_at([0.5], [0.0]))
    whole, area = s.surface, s.surface.area
    assert whole.coverage.windows == 20 and area.counts.windows == 10  # middles 0.5..9.5 s
    assert area.counts.updated == 10 and area.counts.input == 1
    assert area.position.samples == 10 and area.position.rms_m == pytest.approx(3.0)
    assert whole.position.samples == 20
    assert s.airborne.area.counts.windows == 0
    s = score_against_reference(upd, ref)
    assert s.surface.area is None


def test_min_surface_speed_leaves_parked_aircraft_out():
    # parked at x = 0 for 0..30 s, then 10 m/s for 30..60 s
    t = np.arange(61.0)
    x = np.where(t < 30, 0.0, 10 * (t - 30))
    ref = ReferenceSamples(T0 + (t * S).astype(np.int64), np.full(61, 7), x, np.zeros(61),
                           np.ones(61, bool))  # fmt: skip
    cfg = ReferenceScoreConfig(min_surface_speed=1.0, speed_span_s=10.0)
    s = score_against_reference(updates_at([]), ref, cfg)
    # speed over [t-5, t+5] >= 1 m/s when 10 (t + 5 - 30) >= 10, i.e. t >= 26: the
    # windows with middles 26.5 .. 59.5 (34 of 60)
    assert s.surface.coverage.windows == 60 and s.surface.area.counts.windows == 34
    # airborne windows are not restricted by the surface speed
    ref_air = taxiing(v=0.0, ground=False)
    s = score_against_reference(updates_at([]), ref_air, cfg)
    assert s.airborne.area.counts.windows == s.airborne.coverage.windows == 4
