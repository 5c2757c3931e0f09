"""Airborne / surface split of the label measures: hand-built rows whose
measures are counted by hand."""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.metrics.traffic_split import (
    AIRBORNE,
    OVERHEAD,
    SURFACE,
    UNKNOWN,
    split_label_metrics,
    traffic_class,
)


def test_classes_from_flight_level_and_range():
    alt = np.array([0.0, 300.0, 310.0, 3000.0, np.nan])
    rng = np.array([5e3, 5e3, 5e3, 3000.0, 5e3])
    assert traffic_class(alt, rng).tolist() == [SURFACE, SURFACE, AIRBORNE, OVERHEAD, UNKNOWN]


def test_split_counts_track_ids_changes_and_false_tracks_per_class():
    # aircraft 7 airborne on track 1 throughout; aircraft 8 taxiing on tracks 2, 3, 2
    # (2 changes, 2 distinct ids); track 4 confirmed on unlabelled plots (false, surface);
    # aircraft 9 airborne on track 5 then 6 (one change).
    rows = [
        # t, label, track, confirmed, class
        (0, 7, 1, True, AIRBORNE), (4, 7, 1, True, AIRBORNE), (8, 7, 1, True, AIRBORNE),
        (0, 8, 2, True, SURFACE), (4, 8, 3, True, SURFACE), (8, 8, 2, True, SURFACE),
        (1, -1, 4, True, SURFACE), (5, -1, 4, True, SURFACE),
        (2, 9, 5, True, AIRBORNE), (6, 9, 6, True, AIRBORNE), (10, 9, 6, False, AIRBORNE),
    ]  # fmt: skip
    t, lab, trk, conf, cls = (np.array(c) for c in zip(*rows))
    m = split_label_metrics(t.astype(float), lab, trk, conf.astype(bool), cls)
    air, sur, allm = m["airborne"], m["surface"], m["all"]
    assert air["aircraft"] == 2 and air["one_track_share"] == 0.5
    assert air["track_ids_per_aircraft"] == 1.5 and air["id_changes_per_aircraft"] == 0.5
    assert air["confirmed_tracks"] == 3 and air["confirmed_false_tracks"] == 0
    assert sur["aircraft"] == 1 and sur["track_ids_per_aircraft"] == 2.0
    assert sur["id_changes_per_aircraft"] == 2.0
    assert sur["confirmed_tracks"] == 3 and sur["confirmed_false_tracks"] == 1
    assert allm["aircraft"] == 3 and allm["confirmed_tracks"] == 6
    assert allm["false_track_share"] == round(1 / 6, 4)
    assert m["overhead"]["plots"] == 0 and m["overhead"]["track_ids_per_aircraft"] is None
