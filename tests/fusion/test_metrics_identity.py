"""Identity measures (fusion/metrics/identity_metrics.py) against plain-Python loops over
the rows (the definitions written out), on hand-built rows and on random ones."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest
from skyfuse.fusion.metrics import identity_metrics as im
from skyfuse.fusion.metrics.traffic_split import AIRBORNE, SURFACE

S1, S2, S3, S4 = 0x111111, 0x222222, 0x333333, 0x444444
C1, C2 = 101, 202  # packed callsigns stand-ins (any non-negative integers)


def rows(*r) -> im.IdentityRows:
    """Rows (t, track, confirmed, mode_s, callsign, fl, cls, track_mode_s,
    track_callsign, track_fl), scan period 4 s."""
    cols = list(zip(*r))
    n = len(r)
    return im.IdentityRows(
        t=np.array(cols[0], float), track=np.array(cols[1]), confirmed=np.array(cols[2]),
        mode_s=np.array(cols[3]), callsign=np.array(cols[4]), flight_level=np.array(cols[5]),
        cls=np.array(cols[6]), scan_s=np.full(n, 4.0), track_mode_s=np.array(cols[7]),
        track_callsign=np.array(cols[8]), track_flight_level=np.array(cols[9]),
    )  # fmt: skip


NAN = math.nan
HAND = rows(
    # aircraft 1: confirmed at 4, its callsign shown at 8 (within 2 scans + ½)
    (0.0, 1, False, S1, C1, 300.0, AIRBORNE, -1, -1, NAN),
    (4.0, 1, True, S1, C1, 301.0, AIRBORNE, S1, -1, 301.0),
    (8.0, 1, True, S1, C1, 302.0, AIRBORNE, S1, C1, 302.5),
    # aircraft 2: confirmed at 0, its callsign only at 12 (> 0 + 10 s): late; a wrong address
    (0.0, 2, True, S2, C2, 100.0, AIRBORNE, S2, -1, 98.5),
    (4.0, 2, True, S2, C2, NAN, AIRBORNE, S3, -1, 98.5),
    (12.0, 2, True, S2, C2, 102.0, AIRBORNE, S2, C2, NAN),
    # aircraft 3 on the surface, aircraft 4 airborne without a callsign: not scored
    (0.0, 3, True, S3, C1, 0.0, SURFACE, S3, -1, 0.0),
    (0.0, 4, True, S4, -1, 200.0, AIRBORNE, S4, -1, 200.0),
    # a plot without an address on a confirmed track, one on no track
    (4.0, 4, True, -1, -1, 200.0, AIRBORNE, S4, -1, 200.0),
    (5.0, -1, False, S4, -1, NAN, AIRBORNE, -1, -1, NAN),
)


def test_hand_built_rows():
    assert im.mode_s_correct(HAND) == (7, 6 / 7)  # the address S3 shown for S2 at 4 s
    assert im.flight_level_agreement(HAND) == (7, 5 / 7)  # 98.5 vs 100, NaN vs 102 fail
    cs = im.callsign_shown(HAND)
    assert (cs["aircraft"], cs["shown"], cs["missed"]) == (2, 1, [(S2, C2, 0.0)])


def test_conflict_incidents_group_attributes_of_one_track_and_time():
    conflicts = [(10.0, 5, "mode_s", "B", "A"), (10.0, 5, "callsign", "Y", "X"),
                 (3.0, 7, "callsign", "Q", "P")]  # fmt: skip
    assert im.conflict_incidents(conflicts) == [
        {"time_s": 3.0, "track_id": 7, "callsign": ["P", "Q"]},
        {"time_s": 10.0, "track_id": 5, "mode_s": ["A", "B"], "callsign": ["X", "Y"]},
    ]


def reference_callsign(r: im.IdentityRows) -> tuple[int, int]:
    """(aircraft scored, shown) by the definition, one row at a time."""
    scored = shown = 0
    for a in sorted({int(x) for x in r.mode_s if x >= 0}):
        mine = sorted((i for i in range(len(r.t)) if r.mode_s[i] == a), key=lambda i: r.t[i])
        conf = [i for i in mine if r.confirmed[i]]
        if not conf or r.cls[conf[0]] != AIRBORNE:
            continue
        deadline = r.t[conf[0]] + 2.5 * r.scan_s[conf[0]]
        if not any(r.callsign[i] >= 0 and r.t[i] <= deadline for i in mine):
            continue
        counts = Counter(int(r.callsign[i]) for i in mine if r.callsign[i] >= 0)
        best = min(c for c, k in counts.items() if k == max(counts.values()))
        scored += 1
        shown += any(r.track_callsign[i] == best for i in conf if r.t[i] <= deadline)
    return scored, shown


@pytest.mark.parametrize("seed", range(5))
def test_random_rows_against_the_definitions(seed):
    rng = np.random.default_rng(seed)
    n = 600
    ms = rng.choice([-1, S1, S2, S3, S4, 0x555555], n)
    cs = rng.choice([-1, C1, C2, 303], n)
    r = im.IdentityRows(
        t=np.round(rng.uniform(0, 120, n), 1), track=rng.integers(-1, 6, n),
        confirmed=rng.random(n) < 0.7, mode_s=ms, callsign=cs,
        flight_level=np.where(rng.random(n) < 0.8, rng.uniform(0, 400, n), NAN),
        cls=rng.choice([AIRBORNE, SURFACE], n, p=[0.8, 0.2]), scan_s=rng.choice([4.0, 10.0], n),
        track_mode_s=np.where(rng.random(n) < 0.9, ms, S1),
        track_callsign=rng.choice([-1, C1, C2], n),
        track_flight_level=np.where(rng.random(n) < 0.9, rng.uniform(0, 400, n), NAN),
    )  # fmt: skip
    use = [i for i in range(n) if r.confirmed[i] and r.mode_s[i] >= 0]
    assert im.mode_s_correct(r) == (
        len(use), sum(r.track_mode_s[i] == r.mode_s[i] for i in use) / len(use))  # fmt: skip
    fl = [i for i in range(n) if r.confirmed[i] and not math.isnan(r.flight_level[i])]
    ok = sum(abs(r.track_flight_level[i] - r.flight_level[i]) <= 1.0 for i in fl)
    assert im.flight_level_agreement(r) == (len(fl), ok / len(fl))
    cs_ = im.callsign_shown(r)
    assert (cs_["aircraft"], cs_["shown"]) == reference_callsign(r)
