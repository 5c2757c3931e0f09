"""Where the tracks false at confirmation are (fusion.evaluation.summary.false_origin),
against distances worked out by hand on a small history."""

import numpy as np
from skyfuse.fusion.evaluation.summary import false_at_confirmation, false_origin
from skyfuse.fusion.metrics.history import TrackHistory, TruthHistory


def _history():
    truth = TruthHistory(
        run=[0, 0, 0, 0, 1],
        scan=[1, 1, 2, 2, 1],
        target_id=[0, 1, 0, 1, 0],
        position=[[0, 0], [1000, 0], [0, 100], [1000, 100], [5000, 5000]],
    )
    # track 7: confirmed false at (run 0, scan 1) 30 m from target 0, true at scan 2;
    # track 8: confirmed false at scan 2, 4 km from every target, never true;
    # track 9: confirmed true (not counted); track 7 is carried into run 1 (counted once)
    rows = [
        (0, 1, 7, True, -1, [30, 0]),
        (0, 2, 7, True, 0, [0, 95]),
        (0, 1, 8, False, -1, [4000, 0]),
        (0, 2, 8, True, -1, [4000, 100]),
        (0, 1, 9, True, 1, [1000, 0]),
        (1, 1, 7, True, -1, [5000, 5030]),
    ]
    run, scan, tid, conf, lab, pos = zip(*rows)
    tracks = TrackHistory(
        np.array(run), np.array(scan), np.array(tid), np.array(conf), np.array(lab),
        np.array(pos, float),
    )  # fmt: skip
    return tracks, truth


def test_false_origin_distances_and_later_labels_by_hand():
    tracks, truth = _history()
    out = false_origin(tracks, truth)
    np.testing.assert_allclose(out["distance_m"], [30.0, 3000.0])  # tracks 7, 8 in id order
    assert out["true_within_3_scans"].tolist() == [True, False]
    # the same tracks as the count used for the calibration
    assert false_at_confirmation(tracks, np.array([1, 2]))[-1] == 2
