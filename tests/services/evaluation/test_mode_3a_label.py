"""Scoring labels: Mode-S address, else a discrete Mode-3/A code (real data)."""

import numpy as np
from skyfuse.services.evaluation.observers import MODE_3A_LABEL_BASE, mode_3a_fallback


def test_mode_s_wins_and_discrete_mode_3a_fills_in():
    mode_s = np.array([0x4CA73D, -1, -1, -1, -1, 0xFFFFFF])
    mode_3a = np.array([0o7376, 0o7376, 0o7000, -1, 0o7052, -1])
    got = mode_3a_fallback(mode_s, mode_3a)
    # by hand: Mode-S kept; 7376 and 7052 offset above 2^24; 7000 (conspicuity) and
    # a missing code give no label
    want = [0x4CA73D, (1 << 24) + 0o7376, -1, -1, (1 << 24) + 0o7052, 0xFFFFFF]
    assert got.tolist() == want
    assert MODE_3A_LABEL_BASE > 0xFFFFFF
    assert mode_s[1] == -1  # input untouched


def test_no_mode_3a_column_keeps_mode_s():
    mode_s = np.array([5, -1])
    assert mode_3a_fallback(mode_s, None).tolist() == [5, -1]
