"""Loop-by-loop pieces of the reference scorer's brute-force checks
(tests/fusion/test_metrics_reference_brute.py, test_metrics_reference_coverage.py): an
aircraft's samples are ``(t s, x m, y m, ground)`` tuples sorted by time."""

from __future__ import annotations


def interp(samples, t, max_gap):
    """(x, y, ground) of an aircraft at t from its time-sorted samples, or None."""
    for i in range(len(samples) - 1):
        (t0, x0, y0, g0), (t1, x1, y1, g1) = samples[i], samples[i + 1]
        if t0 <= t <= t1:
            if t1 - t0 > max_gap:
                return None
            w = (t - t0) / (t1 - t0) if t1 > t0 else 0.0
            return x0 + w * (x1 - x0), y0 + w * (y1 - y0), (g0 if w < 0.5 else g1)
    return None


def presence_segments(samples, max_gap):
    """The samples cut where the gap exceeds ``max_gap`` s or the phase changes."""
    segs, cur = [], [samples[0]]
    for s in samples[1:]:
        if s[0] - cur[-1][0] > max_gap or s[3] != cur[-1][3]:
            segs.append(cur)
            cur = [s]
        else:
            cur.append(s)
    segs.append(cur)
    return segs
