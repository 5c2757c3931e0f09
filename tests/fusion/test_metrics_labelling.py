"""Truth labelling ([thesis] §7.1, eq. 7.1) on hand-worked examples."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.metrics.labelling import FALSE, TruthLabeller, two_point_covariance

# Per axis P_{2|2} = [[25, 25], [25, 50]]; its inverse is (1/625)[[50, -25], [-25, 25]]
# = [[0.08, -0.04], [-0.04, 0.04]], so for an error (e, ev) on one axis
# d² = 0.08 e² − 0.08 e·ev + 0.04 ev².
P22 = two_point_covariance(25.0, 1.0)


def test_two_point_covariance_layout():
    expected = np.array(
        [[25, 25, 0, 0], [25, 50, 0, 0], [0, 0, 25, 25], [0, 0, 25, 50]], dtype=float
    )
    np.testing.assert_allclose(P22, expected)
    # T = 2 s: [[R, R/T], [R/T, 2R/T²]] = [[25, 12.5], [12.5, 12.5]].
    np.testing.assert_allclose(two_point_covariance(25.0, 2.0)[:2, :2], [[25, 12.5], [12.5, 12.5]])
    # A full R: 3-D with R = diag(25, 25, 100) puts 100 in the z block.
    P3 = two_point_covariance(np.diag([25.0, 25.0, 100.0]), 1.0)
    np.testing.assert_allclose(P3[4:, 4:], [[100, 100], [100, 200]])


@pytest.mark.parametrize(
    ("err", "label"),
    [
        ([10, 0, 0, 0], 0),  # d² = 0.08·100 = 8 < 20: true
        ([15, 0, 0, 0], 0),  # 18 < 20
        ([16, 0, 0, 0], FALSE),  # 20.48
        ([0, 22, 0, 0], 0),  # velocity only: 0.04·484 = 19.36
        ([0, 23, 0, 0], FALSE),  # 21.16
        ([10, 10, 0, 0], 0),  # correlated error: 8 − 8 + 4 = 4
        ([10, -10, 0, 0], FALSE),  # anti-correlated: 8 + 8 + 4 = 20, not < 20
        ([10, 0, 10, 0], 0),  # both axes: 8 + 8 = 16
        ([10, 0, 12, 0], 0),  # 8 + 11.52 = 19.52
        ([10, 0, 13, 0], FALSE),  # 8 + 13.52 = 21.52
    ],
)
def test_new_track_test_7_1(err, label):
    truth = np.array([[100.0, 5.0, 200.0, -3.0]])
    lab = TruthLabeller(P22)
    got = lab.step(
        np.array([1]), truth + np.array(err, float), np.array([0]), truth, np.array([-1])
    )
    assert got.tolist() == [label]


def test_new_track_takes_nearest_passing_target():
    # Targets 0 at x=0 and 1 at x=12; track at x=7: d² = 0.08·49 = 3.92 to target 0 and
    # 0.08·25 = 2 to target 1 -> both pass, nearest is 1.
    truth = np.array([[0.0, 0, 0, 0], [12.0, 0, 0, 0]])
    lab = TruthLabeller(P22)
    got = lab.step(
        np.array([4]), np.array([[7.0, 0, 0, 0]]), np.array([0, 1]), truth, np.array([-1])
    )
    assert got.tolist() == [1]


def test_history_stay_miss_retest_switch_and_loss():
    # Target 0 at x=0, target 1 at x=100 (both still; y = 0). Track 7 starts on target 0,
    # track 8 starts far from both (x=50: d² = 200 and 200) and is false.
    # scan 0: 7 at x=10 (d² 8): true for 0.   8: false.
    # scan 1: 7 at x=60 (d² 288 to 0) but selects a plot of target 0 -> stays 0 (rule 3).
    #         8 at x=97 (d² 0.72 to target 1): false track tested every scan -> true for 1.
    # scan 2: 7 selects nothing: miss 1, keeps 0.   8 selects target 1's plot: stays 1.
    # scan 3: 7 selects only target 1's plot: miss 2, keeps 0 (no test before 3 misses).
    #         8 selects target 1's plot: stays 1.
    # scan 4: 7 selects nothing: miss 3 -> re-test: at x=98 it fails for 0, passes for 1
    #         (d² 0.32) -> switch to 1.   8 misses (1st) and keeps 1.
    # scan 5: 8 misses (2nd), moves away to x=300. keeps 1.
    # scan 6: 8 misses (3rd) at x=300: fails everything -> false (lost).
    truth_ids = np.array([0, 1])
    truth = np.array([[0.0, 0, 0, 0], [100.0, 0, 0, 0]])
    lab = TruthLabeller(P22)

    def step(x7, sel7, x8, sel8):
        states = np.array([[x7, 0, 0, 0], [x8, 0, 0, 0]], dtype=float)
        return lab.step(np.array([7, 8]), states, truth_ids, truth, np.array([sel7, sel8])).tolist()

    assert step(10, -1, 50, -1) == [0, FALSE]
    assert step(60, 0, 97, -1) == [0, 1]
    assert step(60, -1, 97, 1) == [0, 1]
    assert step(98, 1, 97, 1) == [0, 1]
    assert step(98, -1, 97, -1) == [1, 1]
    assert step(98, 1, 300, -1) == [1, 1]
    assert step(98, 1, 300, -1) == [1, FALSE]


def test_retest_keeps_label_when_target_still_passes_and_track_forgotten_when_absent():
    # Three misses in a row while still within 7.1 of its target: the label stays.
    truth = np.array([[0.0, 0, 0, 0]])
    lab = TruthLabeller(P22, retest_after=3)
    for _ in range(5):
        got = lab.step(
            np.array([3]), np.array([[5.0, 0, 0, 0]]), np.array([0]), truth, np.array([-1])
        )
        assert got.tolist() == [0]
    # Track 3 disappears for one scan (terminated); an id re-used later is a new track.
    lab.step(np.zeros(0, dtype=int), np.zeros((0, 4)), np.array([0]), truth, np.zeros(0, dtype=int))
    assert lab.label_of(3) == FALSE
    far = np.array([[500.0, 0, 0, 0]])
    assert lab.step(np.array([3]), far, np.array([0]), truth, np.array([0])).tolist() == [FALSE]


def test_selection_with_several_plots_and_weights():
    # Track 1 true for target 0 (scan 0). Then it is far (x=80) and its gate holds plots of
    # targets 2 and 0 (padded (m, q) form): it selected t's plot -> no miss.
    # With weights [0.9, 0.05] and min_weight 0.1 only target 2's plot counts: misses.
    truth_ids = np.array([0, 2])
    truth = np.array([[0.0, 0, 0, 0], [80.0, 0, 0, 0]])
    lab = TruthLabeller(P22, retest_after=2)
    x = np.array([[1.0, 0, 0, 0]])
    assert lab.step(np.array([1]), x, truth_ids, truth, np.array([[-1, -1]])).tolist() == [0]
    far = np.array([[80.0, 0, 0, 0]])
    sel = np.array([[2, 0]])
    for _ in range(3):
        assert lab.step(np.array([1]), far, truth_ids, truth, sel).tolist() == [0]
    w = np.array([[0.9, 0.05]])
    assert lab.step(np.array([1]), far, truth_ids, truth, sel, w, 0.1).tolist() == [0]  # miss 1
    assert lab.step(np.array([1]), far, truth_ids, truth, sel, w, 0.1).tolist() == [2]  # miss 2


def test_labeller_rejects_bad_input():
    with pytest.raises(ValueError, match="positive definite"):
        TruthLabeller(np.zeros((4, 4)))
    lab = TruthLabeller(P22)
    with pytest.raises(ValueError, match="track_states: shape"):
        lab.step(np.array([1]), np.zeros((1, 2)), np.array([0]), np.zeros((1, 4)), np.array([-1]))
    with pytest.raises(ValueError, match="truth_ids: target ids must be >= 0"):
        lab.step(np.array([1]), np.zeros((1, 4)), np.array([-1]), np.zeros((1, 4)), np.array([-1]))
    with pytest.raises(ValueError, match="selected_targets"):
        lab.step(np.array([1]), np.zeros((1, 4)), np.array([0]), np.zeros((1, 4)), np.array([0.5]))


def _reference_labels(scans, P_inv, threshold=20.0, retest_after=3):
    """The four rules written as a plain per-track loop (dicts), as an independent check."""
    state: dict[int, tuple[int, int]] = {}
    out = []
    for tids, xs, gids, gx, sel in scans:
        new_state, labels = {}, []
        for tid, x, s in zip(tids.tolist(), xs, sel.tolist()):
            d2 = {g: float((x - y) @ P_inv @ (x - y)) for g, y in zip(gids.tolist(), gx)}
            ok = {g: d for g, d in d2.items() if d < threshold}
            nearest = min(ok, key=ok.get) if ok else FALSE
            label, misses = state.get(tid, (FALSE, 0))
            if label == FALSE:
                label, misses = nearest, 0
            elif s == label:
                misses = 0
            else:
                misses += 1
                if misses >= retest_after and label not in ok:
                    label, misses = nearest, 0
            new_state[tid] = (label, misses)
            labels.append(label)
        state = new_state
        out.append(labels)
    return out


def test_vectorised_labeller_matches_plain_rules_on_random_histories():
    rng = np.random.default_rng(11)
    P_inv = np.linalg.inv(P22)
    scans = []
    for _ in range(80):
        # Persistent ids (each present with probability 0.9) so that misses accumulate.
        gids = np.flatnonzero(rng.random(4) < 0.9)
        gx = rng.normal(0, 12, size=(len(gids), 4))
        tids = np.flatnonzero(rng.random(5) < 0.9) + 10
        xs = rng.normal(0, 12, size=(len(tids), 4))
        sel = np.where(rng.random(len(tids)) < 0.6, -1, rng.integers(0, 4, size=len(tids)))
        scans.append((tids, xs, gids, gx, sel))
    lab = TruthLabeller(P22)
    got = [lab.step(*s).tolist() for s in scans]
    assert got == _reference_labels(scans, P_inv)
    # The history exercises every transition: false->true, true->other target, true->false.
    kinds = set()
    for k in range(1, len(scans)):
        prev = dict(zip(scans[k - 1][0].tolist(), got[k - 1]))
        for t, now in zip(scans[k][0].tolist(), got[k]):
            was = prev.get(t, FALSE)
            if was == FALSE and now != FALSE:
                kinds.add("found")
            elif was != FALSE and now == FALSE:
                kinds.add("lost")
            elif was != FALSE and now != was:
                kinds.add("switched")
    assert kinds == {"found", "lost", "switched"}
