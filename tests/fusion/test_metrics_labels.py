"""Label-only measures (Mode-S addresses on plots) on a scripted plot/track history."""

from __future__ import annotations

import math

import numpy as np
import pytest
from skyfuse.fusion.metrics.label_metrics import label_metrics

A, B, C = 0xABC, 0x123, 0x777
N = -1
# (time s, label, track id, track confirmed at that time)
PLOTS = [
    (0, A, N, False),
    (4, A, 1, False),
    (8, A, 1, True),  # A first held by a confirmed track: time to confirm 8 - 0 = 8 s
    (12, A, 1, True),
    (16, A, 2, True),  # change 1 (1 -> 2)
    (20, A, 1, True),  # change 2 (2 -> 1)
    (22, A, 7, True),  # change 3 (1 -> 7)
    (2, B, 3, False),
    (6, B, 3, True),  # B: time to confirm 6 - 2 = 4 s
    (10, B, 3, True),
    (23, B, 7, True),  # B change 1 (3 -> 7)
    (5, C, N, False),
    (9, C, 4, False),  # C is never held by a confirmed track
    (3, N, 5, False),
    (7, N, 5, True),  # track 5: only unlabelled plots while confirmed -> share 0: false
    (11, N, 5, True),
    (15, N, 5, True),
    (14, N, 1, True),  # track 1: A, A, unlabelled, A, A -> 3/4 >= 0.5: true  (plots 8,12,14,20)
    (17, N, 2, True),  # track 2: A, N, N -> 1/3 < 0.5: false
    (18, N, 2, True),
]  # track 3: B, B -> true; track 7: A, B -> 1/2 >= 0.5: true


def _cols(rows):
    t, lab, trk, conf = zip(*rows)
    return np.array(t, float), np.array(lab), np.array(trk), np.array(conf, dtype=bool)


def test_label_metrics_scripted():
    r = label_metrics(*_cols(PLOTS), duration_s=1800.0)
    assert r.aircraft.tolist() == sorted([A, B, C])  # [0x123, 0x777, 0xABC]
    assert r.has_confirmed.tolist() == [True, False, True]
    assert r.completeness == pytest.approx(2 / 3)
    assert r.id_changes.tolist() == [1, 0, 3]
    assert r.mean_id_changes == pytest.approx(4 / 3)
    assert r.confirmed_tracks.tolist() == [1, 2, 3, 5, 7]
    assert r.false_tracks.tolist() == [2, 5]
    assert r.false_per_hour == pytest.approx(4.0)  # 2 false tracks in half an hour
    assert r.time_to_confirm[0] == 4 and math.isnan(r.time_to_confirm[1])
    assert r.time_to_confirm[2] == 8
    assert r.mean_time_to_confirm == pytest.approx(6.0)


def test_label_metrics_order_free_warmup_and_default_duration():
    rows = list(PLOTS)
    np.random.default_rng(3).shuffle(rows)
    # Warm-up 1 s: A (first plot at t=0) is excluded from the mean time to confirm -> 4 s.
    r = label_metrics(*_cols(rows), warmup_s=1.0)
    assert r.mean_time_to_confirm == pytest.approx(4.0)
    assert r.id_changes.tolist() == [1, 0, 3]
    # Duration defaults to the plot time span, 23 s: 2 / (23/3600) per hour.
    assert r.duration_s == 23 and r.false_per_hour == pytest.approx(2 * 3600 / 23)
    # A stricter share (0.8) also makes track 1 (3/4) false.
    assert label_metrics(*_cols(rows), min_label_share=0.8).false_tracks.tolist() == [1, 2, 5, 7]


def test_label_metrics_empty_and_bad_input():
    r = label_metrics(np.zeros(0), np.zeros(0, int), np.zeros(0, int), np.zeros(0, bool))
    assert math.isnan(r.completeness) and len(r.aircraft) == 0 and len(r.false_tracks) == 0
    t, lab, trk, conf = _cols(PLOTS)
    with pytest.raises(ValueError, match="plot_track: value -2"):
        label_metrics(t, lab, np.full(len(t), -2), conf)
    with pytest.raises(ValueError, match="plot_track = -1"):
        label_metrics(t, lab, np.full(len(t), -1), np.ones(len(t), bool))
    with pytest.raises(ValueError, match="plot_label: shape"):
        label_metrics(t, lab[:-1], trk, conf)
