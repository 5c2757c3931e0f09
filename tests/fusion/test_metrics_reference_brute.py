"""Reference scores against a brute-force implementation of the same definitions,
written with plain loops over samples, updates and windows (no searchsorted, no
cumulative sums), on random scenes: aircraft with gaps and phase changes, tracks that
follow them with offsets, swap, duplicate or wander."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reference_brute_support import interp, presence_segments
from skyfuse.fusion.metrics.reference_association import ReferenceSamples, TrackUpdates
from skyfuse.fusion.metrics.reference_scores import ReferenceScoreConfig, score_against_reference

T0 = 1_600_000_000 * 10**9


def scene(seed: int):
    """Random reference aircraft and track updates (arrays)."""
    rng = np.random.default_rng(seed)
    n_ac = int(rng.integers(1, 4))
    rows = []
    paths = []
    for a in range(n_ac):
        p0, v = rng.uniform(-400, 400, 2), rng.uniform(-40, 40, 2)
        t = np.cumsum(
            rng.choice([0.4, 0.5, 1.0, 5.0, 9.0], size=120, p=[0.3, 0.3, 0.3, 0.07, 0.03])
        )
        t = t[t < 80] + rng.uniform(0, 0.01)
        switch = rng.uniform(0, 100)
        g = (t < switch) if rng.random() < 0.5 else (t >= switch)
        paths.append((p0, v))
        for ti, gi in zip(t, g):
            rows.append((ti, 0x100 + a, *(p0 + v * ti), gi))
    ref = np.array(rows, dtype=object)
    upd = []
    for k in range(int(rng.integers(1, 5))):
        a = int(rng.integers(0, n_ac + 1))  # n_ac: a track on nothing
        p0, v = paths[a] if a < n_ac else (rng.uniform(-400, 400, 2), rng.uniform(-40, 40, 2))
        off = rng.normal(0, 15, 2)
        t = np.sort(rng.uniform(*np.sort(rng.uniform(0, 80, 2)), size=int(rng.integers(5, 60))))
        for ti in t:
            upd.append((ti, k, *(p0 + v * ti + off + rng.normal(0, 4, 2))))
    return ref, np.array(upd, dtype=float).reshape(-1, 4)


def to_inputs(ref, upd):
    r = ReferenceSamples(
        T0 + np.round(ref[:, 0].astype(float) * 1e9).astype(np.int64),
        ref[:, 1].astype(np.int64), ref[:, 2].astype(float), ref[:, 3].astype(float),
        ref[:, 4].astype(bool),
    )  # fmt: skip
    u = TrackUpdates(
        T0 + np.round(upd[:, 0] * 1e9).astype(np.int64), upd[:, 1].astype(np.int64),
        upd[:, 2], upd[:, 3],
    )  # fmt: skip
    return r, u


# ---- brute force ----------------------------------------------------------------------


def brute(r: ReferenceSamples, u: TrackUpdates, cfg: ReferenceScoreConfig):
    epoch = min(r.time_ns.min(), u.time_ns.min())
    ac = {}
    for i in range(len(r)):
        ac.setdefault(int(r.key[i]), []).append(
            ((r.time_ns[i] - epoch) * 1e-9, r.x[i], r.y[i], bool(r.ground[i]))
        )
    ac = {k: sorted(v) for k, v in sorted(ac.items()) if len(v) >= cfg.min_reference_samples}
    t = [(u.time_ns[i] - epoch) * 1e-9 for i in range(len(u))]
    labels, dists = [], []
    for i in range(len(u)):
        best, best_d = None, math.inf
        for k, smp in ac.items():
            p = interp(smp, t[i], cfg.max_reference_gap_s)
            if p is None:
                continue
            d = math.hypot(u.x[i] - p[0], u.y[i] - p[1])
            gate = cfg.gate_surface_m if p[2] else cfg.gate_airborne_m
            if d <= gate and d < best_d:
                best, best_d = k, d
        labels.append(best)
        dists.append(best_d)
    assigned = []
    for i in range(len(u)):
        count, dsum = {}, {}
        for j in range(len(u)):
            if u.track_id[j] == u.track_id[i] and abs(t[j] - t[i]) <= cfg.majority_window_s / 2:
                count[labels[j]] = count.get(labels[j], 0) + 1
                if labels[j] is not None:
                    dsum[labels[j]] = dsum.get(labels[j], 0.0) + dists[j]
        top = max(count.values())
        tied = [k for k, c in count.items() if c == top and k is not None]
        assigned.append(min(tied, key=lambda k: dsum[k] / count[k]) if tied else None)
    return ac, t, assigned


def brute_scores(r, u, cfg):
    ac, t, assigned = brute(r, u, cfg)
    credited = []  # (aircraft, track, t, squared error, ground)
    for i, a in enumerate(assigned):
        if a is None:
            continue
        p = interp(ac[a], t[i], cfg.max_reference_gap_s)
        if p is not None:
            sq = (u.x[i] - p[0]) ** 2 + (u.y[i] - p[1]) ** 2
            credited.append((a, int(u.track_id[i]), t[i], sq, p[2]))
    out = {g: {"windows": 0, "updated": 0, "changes": 0, "dup": 0} for g in (True, False)}
    for a, smp in ac.items():
        mine = [c for c in credited if c[0] == a]
        first = {}
        for c in sorted(mine, key=lambda c: c[2]):
            first.setdefault(c[1], c[2])
        segs = presence_segments(smp, cfg.max_reference_gap_s)
        last_holder = None
        for seg in segs:
            g = seg[0][3]
            width = cfg.surface_window_s if g else cfg.airborne_window_s
            k = 0
            while seg[0][0] + (k + 1) * width <= seg[-1][0] + 1e-9:
                lo, hi = seg[0][0] + k * width, seg[0][0] + (k + 1) * width
                tracks = {c[1] for c in mine if lo <= c[2] < hi}
                out[g]["windows"] += 1
                if tracks:
                    out[g]["updated"] += 1
                    out[g]["dup"] += len(tracks) >= 2
                    holder = min(tracks, key=lambda x: first[x])
                    if last_holder is not None and holder != last_holder:
                        out[g]["changes"] += 1
                    last_holder = holder
                k += 1
    for g in (True, False):
        sq = [c[3] for c in credited if c[4] == g]
        out[g]["rms"] = math.sqrt(sum(sq) / len(sq)) if sq else math.nan
        pairs = {(c[0], c[1]) for c in credited if c[4] == g}
        per = [sum(1 for p in pairs if p[0] == a) for a in {p[0] for p in pairs}]
        out[g]["ids"] = sum(per) / len(per) if per else math.nan
    return assigned, out, sorted(ac)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_scores_equal_a_brute_force_implementation(seed):
    ref, upd = scene(seed)
    r, u = to_inputs(ref, upd)
    cfg = ReferenceScoreConfig(min_reference_samples=5)
    s = score_against_reference(u, r, cfg)
    assigned, want, keys = brute_scores(r, u, cfg)
    got_assigned = [None if a < 0 else int(s.aircraft_keys[a]) for a in s.association.assigned]
    assert got_assigned == assigned
    assert list(s.aircraft_keys) == keys
    for g, phase in ((True, s.surface), (False, s.airborne)):
        w = want[g]
        assert (phase.windows, phase.windows_updated) == (w["windows"], w["updated"])
        assert phase.id_changes == w["changes"] and phase.duplicate_windows == w["dup"]
        assert phase.position.rms_m == pytest.approx(w["rms"], nan_ok=True, rel=1e-9)
        assert phase.track_ids_per_aircraft == pytest.approx(w["ids"], nan_ok=True)
