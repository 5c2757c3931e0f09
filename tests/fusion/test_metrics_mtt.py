"""CTT rate, confirmed false tracks, RMSE and the retention table on scripted histories."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from skyfuse.fusion.metrics.history import TrackHistory, TruthHistory
from skyfuse.fusion.metrics.mtt_measures import (
    confirmed_false_tracks,
    ctt_rate,
    gospa_curves,
    rmse_confirmed_true,
)
from skyfuse.fusion.metrics.retention import (
    ROW_KEYS,
    RetentionCounts,
    retention_counts,
    retention_markdown,
)

F = -1  # false label


def _tracks(rows):
    """rows: (run, scan, track_id, confirmed, label, x, y[, psi])."""
    a = list(zip(*rows))
    psi = a[7] if len(a) > 7 else None
    return TrackHistory(
        run=np.array(a[0]),
        scan=np.array(a[1]),
        track_id=np.array(a[2]),
        confirmed=np.array(a[3], dtype=bool),
        label=np.array(a[4]),
        position=np.column_stack([a[5], a[6]]).astype(float),
        existence=None if psi is None else np.array(psi, float),
    )


# Two runs, targets 0 at (0,0) and 1 at (100,0). Run 1 has no target 1 at scan 4.
TRUTH = TruthHistory(
    run=np.array([0] * 8 + [1] * 7),
    scan=np.array([1, 1, 2, 2, 3, 3, 4, 4, 1, 1, 2, 2, 3, 3, 4]),
    target_id=np.array([0, 1] * 4 + [0, 1] * 3 + [0]),
    position=np.array([[0, 0], [100, 0]] * 4 + [[0, 0], [100, 0]] * 3 + [[0, 0]], dtype=float),
)
HIST = _tracks(
    [
        # run 0
        (0, 2, 1, True, 0, 3, 4),  # confirmed true for 0, error 5
        (0, 2, 2, False, 1, 100, 0),  # true for 1 but not confirmed
        (0, 2, 3, True, F, 50, 50),  # confirmed false (first time: scan 2)
        (0, 3, 1, True, 0, 0, 2),  # error 2
        (0, 3, 4, True, 0, 6, 8),  # duplicate on target 0, error 10
        (0, 3, 2, True, 1, 101, 0),  # now confirmed, error 1
        (0, 3, 3, True, F, 50, 50),  # same false track: not counted again
        (0, 4, 1, True, 0, 0, 0),  # error 0
        (0, 4, 2, True, F, 150, 0),  # track 2 lost: a confirmed false track from scan 4
        # run 1
        (1, 1, 3, True, F, 50, 50),  # track 3 carried over: still counted once overall
        (1, 1, 5, True, F, 70, 70),  # new confirmed false track at scan 1
        (1, 2, 6, True, 1, 100, 6),  # error 6
        (1, 3, 6, True, 1, 100, 6),  # error 6
        (1, 4, 6, True, 1, 100, 6),  # target 1 absent at scan 4: skipped by CTT and RMSE
    ]
)
SCANS = np.arange(1, 5)


def test_ctt_rate_scripted():
    # (run, target) pairs present: 4, 4, 4, 3 at scans 1..4.
    # scan 1: none covered -> 0 %.
    # scan 2: run0/T0 (track 1), run1/T1 (track 6); run0/T1 only unconfirmed -> 2/4 = 50 %.
    # scan 3: run0/T0 (tracks 1 and 4 count once), run0/T1, run1/T1 -> 3/4 = 75 %.
    # scan 4: run0/T0 only (track 2 false, run1/T0 has none) -> 1/3.
    np.testing.assert_allclose(ctt_rate(HIST, TRUTH, SCANS), [0, 50, 75, 100 / 3])


def test_confirmed_false_tracks_scripted():
    # First confirmed-and-false scan per distinct track: 3 at run0/scan2, 2 at run0/scan4,
    # 5 at run1/scan1 (track 3 in run 1 is the carried-over one) -> new per scan 1,1,0,1.
    assert confirmed_false_tracks(HIST, SCANS).tolist() == [1, 2, 2, 3]


def test_rmse_scripted():
    # scan 2: errors² 25 (track 1) and 36 (track 6) -> sqrt(61/2).
    # scan 3: 4 + 100 + 1 + 36 = 141 over 4 -> sqrt(35.25).
    # scan 4: track 1 error 0; track 6's target absent -> skipped: 0 over 1.
    rmse, count = rmse_confirmed_true(HIST, TRUTH, SCANS)
    assert count.tolist() == [0, 2, 4, 1]
    assert math.isnan(rmse[0])
    np.testing.assert_allclose(rmse[1:], [math.sqrt(30.5), math.sqrt(35.25), 0.0])


def test_history_rejects_bad_columns():
    with pytest.raises(ValueError, match="confirmed"):
        TrackHistory(
            run=np.array([0]),
            scan=np.array([1]),
            track_id=np.array([1]),
            confirmed=np.array([1]),
            label=np.array([0]),
            position=np.zeros((1, 2)),
        )
    with pytest.raises(ValueError, match="label: value -2"):
        _tracks([(0, 1, 1, True, -2, 0, 0)])
    with pytest.raises(ValueError, match="scans"):
        ctt_rate(HIST, TRUTH, np.array([3, 1]))


# ------------------------------------------------------------------------- retention table
# Scripted history around k_start = 14 and k_end = 38, targets 0, 1, 2 in two runs.
# run 0: T0 track 10 true at 14 and 38                          -> OK
#        T1 track 11 true at 14, true for target 2 at 38         -> switched
#        T2 tracks 12 (ψ .97) and 13 (ψ .999) both confirmed true at 14: the case is 13
#           (highest ψ); 13 is merged into 12 at scan 20          -> lost, merged
#        track 14 true for 0 but unconfirmed at 14, track 15 confirmed false: no cases
# run 1: T0 track 20 true at 14, false at 38                     -> lost (not merged)
#        T1 no confirmed true track at 14 (track 21 confirmed only later): no case
#        T2 track 22 true at 14, terminated before 38; a merge record for it at scan 40
#           lies outside (14, 38]                                 -> lost, not merged
# nCases 5: OK 1, switched 1, lost 3 (60 %), merged 1.
RET = _tracks(
    [
        (0, 14, 10, True, 0, 0, 0, 0.99),
        (0, 14, 11, True, 1, 0, 0, 0.99),
        (0, 14, 12, True, 2, 0, 0, 0.97),
        (0, 14, 13, True, 2, 0, 0, 0.999),
        (0, 14, 14, False, 0, 0, 0, 0.5),
        (0, 14, 15, True, F, 0, 0, 0.96),
        (0, 38, 10, True, 0, 0, 0, 0.99),
        (0, 38, 11, True, 2, 0, 0, 0.99),
        (0, 38, 12, True, 2, 0, 0, 0.99),
        (0, 38, 14, True, 0, 0, 0, 0.99),
        (1, 14, 20, True, 0, 0, 0, 0.99),
        (1, 14, 22, True, 2, 0, 0, 0.99),
        (1, 20, 21, True, 1, 0, 0, 0.99),
        (1, 38, 20, True, F, 0, 0, 0.99),
        (1, 38, 21, True, 1, 0, 0, 0.99),
    ]
)
MERGED = (np.array([0, 1, 1]), np.array([13, 22, 23]), np.array([20, 40, 10]))


def test_retention_scripted_three_targets():
    c = retention_counts(RET, *MERGED, k_start=14, k_end=38, cpu_s=1.5)
    assert (c.n_cases, c.n_ok, c.n_switched, c.n_lost, c.merged) == (5, 1, 1, 3, 1)
    row = c.row("lmits", 7)
    assert tuple(row) == ROW_KEYS
    assert row["nOK"] == pytest.approx(20) and row["nSwitched"] == pytest.approx(20)
    assert row["nLost"] == pytest.approx(60) and row["merged"] == 1 and row["cpu_s"] == 1.5
    json.dumps(row)  # a valid JSON row


def test_retention_accumulates_over_runs_and_without_psi_takes_oldest():
    per_run = [
        retention_counts(
            _tracks([r for r in zip(*_cols(RET)) if r[0] == run]),
            *MERGED,
            k_start=14,
            k_end=38,
        )
        for run in (0, 1)
    ]
    total = per_run[0] + per_run[1]
    assert (total.n_cases, total.n_ok, total.n_switched, total.n_lost, total.merged) == (
        5,
        1,
        1,
        3,
        1,
    )
    # Without ψ the duplicate case on run0/T2 takes track 12 (smallest id), which is still
    # true for target 2 at 38: OK 2, switched 1, lost 2, merged 0.
    no_psi = TrackHistory(RET.run, RET.scan, RET.track_id, RET.confirmed, RET.label, RET.position)
    c = retention_counts(no_psi, *MERGED)
    assert (c.n_cases, c.n_ok, c.n_switched, c.n_lost, c.merged) == (5, 2, 1, 2, 0)


def _cols(h):
    return (
        h.run.tolist(),
        h.scan.tolist(),
        h.track_id.tolist(),
        h.confirmed.tolist(),
        h.label.tolist(),
        h.position[:, 0].tolist(),
        h.position[:, 1].tolist(),
        h.existence.tolist(),
    )


def test_retention_markdown_and_empty():
    empty = RetentionCounts()
    assert empty.row("its", 1)["nOK"] is None
    md = retention_markdown(
        [RetentionCounts(4, 3, 0, 1, 1, 2.0).row("its", 3), empty.row("its", 1)]
    )
    lines = md.strip().splitlines()
    assert lines[0] == "| tracker | depth | nCases | nOK | nSwitched | nLost | merged | cpu_s |"
    assert lines[2] == "| its | 3 | 4 | 75.0 | 0.0 | 25.0 | 1 | 2.00 |"
    assert lines[3].startswith("| its | 1 | 0 | – |")
    with pytest.raises(ValueError, match="k_start"):
        retention_counts(RET, *MERGED, k_start=38, k_end=14)


def test_concat_of_per_run_histories_gives_the_same_measures():
    parts = [
        TrackHistory(
            HIST.run[m],
            HIST.scan[m],
            HIST.track_id[m],
            HIST.confirmed[m],
            HIST.label[m],
            HIST.position[m],
        )
        for m in (HIST.run == 0, HIST.run == 1)
    ]
    truth_parts = [
        TruthHistory(TRUTH.run[m], TRUTH.scan[m], TRUTH.target_id[m], TRUTH.position[m])
        for m in (TRUTH.run == 0, TRUTH.run == 1)
    ]
    h, g = TrackHistory.concat(parts), TruthHistory.concat(truth_parts)
    np.testing.assert_allclose(ctt_rate(h, g, SCANS), [0, 50, 75, 100 / 3])
    assert confirmed_false_tracks(h, SCANS).tolist() == [1, 2, 2, 3]
    assert len(TrackHistory.concat([])) == 0 and len(TruthHistory.concat([])) == 0


def test_gospa_curves_scripted():
    # c = 10, p = 2, gamma = 4, confirmed tracks only (track 2 at scan 2 is left out).
    # run 0: scan 1 no tracks: 2 missed = 100.
    #        scan 2 truth0-track1 d=5 (25); truth1 vs track3 (50,50) d=70.7 > c: 50 + 50 = 125
    #        scan 3 truth0-track1 (4) + truth1-track2 (1); tracks 4 and 3 false: 105
    #        scan 4 truth0-track1 (0); truth1 vs track2 at 50 m: 50 + 50 = 100; truth 1 goes
    #               from track 2 to unassigned: half switch, gamma^2/2 * 1/2 = 4
    # run 1: scan 1 tracks 3, 5 far from both truths: 100 + 100 = 200
    #        scans 2, 3 truth1-track6 (36) + truth0 missed (50) = 86
    #        scan 4 truth0 only, track 6 far: 50 + 50 = 100 (absent truth 1: no switch)

    g = gospa_curves(HIST, TRUTH, SCANS, c=10, p=2, switch_penalty=4)
    r0 = np.sqrt([100, 125, 105, 100])
    r1 = np.sqrt([200, 86, 86, 100])
    np.testing.assert_allclose(g.distance, (r0 + r1) / 2)
    np.testing.assert_allclose(g.missed, [100, 50, 25, 50])
    np.testing.assert_allclose(g.false, [50, 25, 50, 50])
    np.testing.assert_allclose(g.switching, [0, 0, 0, 2])
    assert g.half_switches.tolist() == [0, 0, 0, 1] and g.full_switches.tolist() == [0, 0, 0, 0]
    assert g.runs == 2
    assert g.total == pytest.approx((math.sqrt(434) + math.sqrt(472)) / 2)
