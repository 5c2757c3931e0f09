"""Time that cannot be hijacked (docs/reliability.md §2): the reorder buffer keeps one
watermark per radar, refuses batches from the future of the receiver's clock, applies a
lagging radar's batches (marked late) within ``max_lateness`` and refuses older ones,
and estimates each radar's clock offset. The arrival clock and the receiver's wall clock
are given explicitly, so each case is exact."""

from __future__ import annotations

import pytest
from skyfuse.schemas import PlotBatch
from skyfuse.services.fusion.reorder import ReorderBuffer

T = 1_790_000_000_000_000_000  # receiver wall clock at arrival 0, ns
S = 1_000_000_000


def b(radar: str, t: int, seq: int = 0) -> PlotBatch:
    return PlotBatch(
        radar_id=radar, scan=0, seq=seq, time_start=t - S // 4, time_end=t,
        time=[t - 1000, t], range=[10_000.0, 20_000.0], azimuth=[0.1, 0.2],
    )  # fmt: skip


def test_poison_future_batch_is_refused_and_never_advances_time():
    buf = ReorderBuffer(0.5, future_tolerance=1.0)
    assert buf.push(b("X", T + 3600 * S), 0.0, recv_ns=T) == "time in the future"
    assert buf.push(b("Y", T + 2 * S), 0.0, recv_ns=T) == "time in the future"
    assert len(buf) == 0 and buf.last_time is None
    released = []
    for k in range(35):  # a good radar afterwards: every batch is taken, in order
        arrival = k * 0.25
        t = T + k * S // 4
        assert buf.push(b("A", t, seq=k), arrival, recv_ns=t + 5_000_000) is None
        released += buf.pop_ready(arrival, wall_ns=t + 5_000_000)
    released += buf.flush()
    assert [p.batch.seq for p in released] == list(range(35))
    assert buf.last_time == T + 34 * S // 4
    # a plot time (not only time_end) ahead of the clock is caught too
    sneaky = b("A", T + 40 * S)
    sneaky.time = [T + 40 * S, T + 50 * S]
    assert buf.push(sneaky, 9.0, recv_ns=T + 40 * S) == "time in the future"
    # within the tolerance is fine
    assert buf.push(b("Z", T + 9 * S + S // 2), 9.0, recv_ns=T + 9 * S) is None


def test_one_watermark_per_radar():
    buf = ReorderBuffer(0.0, future_tolerance=None, max_lateness=2.0)
    assert buf.push(b("A", T + 10 * S), 0.0) is None
    assert len(buf.pop_ready(0.0)) == 1
    # another radar, 0.5 s behind the service time: taken and released as late
    assert buf.push(b("B", T + 9 * S + S // 2, seq=1), 0.1) is None
    (p,) = buf.pop_ready(0.1, wall_ns=T + 20 * S)
    assert p.late and p.batch.radar_id == "B"
    # behind its *own* radar's watermark: out of sequence
    assert buf.push(b("B", T + 9 * S, seq=2), 0.2) == "out of sequence"
    # a new radar 2.5 s behind the service time: beyond max_lateness
    assert buf.push(b("C", T + 7 * S + S // 2), 0.3) == "too late"
    assert buf.radar_time == {"A": T + 10 * S, "B": T + 9 * S + S // 2}
    assert buf.push(b("A", T + 10 * S), 0.4) == "duplicate batch"


def simulate(lags: dict[str, float], wait: float = 0.5, n: int = 40, **kw):
    """Radars publishing a batch every 0.25 s of their own clock; radar r's batch stamped
    t arrives at wall time t - T + lags[r] (a lagging clock or link: lag > 0, a clock
    ahead: lag < 0). Returns the buffer, the refusals and the release delays."""
    buf = ReorderBuffer(wait, **kw)
    events = sorted((k * 0.25 + lag, r, k) for r, lag in lags.items() for k in range(n))
    refused: dict[str, list[str]] = {r: [] for r in lags}
    arrived: dict[tuple[str, int], float] = {}
    delays: dict[str, list[float]] = {r: [] for r in lags}
    late: dict[str, int] = dict.fromkeys(lags, 0)
    clock = 0.0
    for arrival, r, k in events:
        # release what fell due before this arrival (a 10 ms service loop)
        while clock <= arrival:
            for p in buf.pop_ready(clock, wall_ns=T + round(clock * S)):
                rid = p.batch.radar_id
                delays[rid].append(clock - arrived[rid, p.batch.seq])
                late[rid] += p.late
            clock += 0.01
        t = T + k * S // 4
        reason = buf.push(b(r, t, seq=k), arrival, recv_ns=T + round(arrival * S))
        if reason is None:
            arrived[r, k] = arrival
        else:
            refused[r].append(reason)
    for p in buf.flush():
        late[p.batch.radar_id] += p.late
    return buf, refused, delays, late


def test_lagging_radar_keeps_contributing():
    # lag 1.0 s: more than the 0.5 s reorder wait (a global watermark refused it all)
    buf, refused, _, late = simulate({"A": 0.0, "L": 1.0}, future_tolerance=1.0)
    assert refused == {"A": [], "L": []}
    assert late["L"] >= 35 and late["A"] == 0
    assert buf.clock_offset("L") == pytest.approx(-1.0, abs=1e-6)
    assert buf.clock_offset("A") == pytest.approx(0.0, abs=1e-6)
    # beyond max_lateness the lagging radar is refused and counted, the other is intact
    buf, refused, _, _ = simulate({"A": 0.0, "L": 3.0}, max_lateness=2.0)
    assert refused["A"] == [] and refused["L"] and set(refused["L"]) == {"too late"}


def test_leading_radar_does_not_delay_the_others():
    buf, refused, delays, late = simulate({"A": 0.0, "B": 0.05, "F": -0.8}, future_tolerance=1.0)
    assert refused == {"A": [], "B": [], "F": []}
    for r in ("A", "B"):  # held the reorder wait, never waiting for F's future times
        assert max(delays[r]) == pytest.approx(0.5, abs=0.011)
    assert late == {"A": 0, "B": 0, "F": 0}  # F never drags the service time ahead
    # F itself waits until this host's clock reaches its times: its own lead, 0.8 s
    assert min(delays["F"]) == pytest.approx(0.8, abs=0.011)
    assert buf.clock_offset("F") == pytest.approx(0.8, abs=1e-6)
    # 2 s ahead: beyond the tolerance, refused, and its offset is still reported
    buf, refused, delays, _ = simulate({"A": 0.0, "F": -2.0}, future_tolerance=1.0)
    assert set(refused["F"]) == {"time in the future"} and len(refused["F"]) == 40
    assert refused["A"] == [] and max(delays["A"]) == pytest.approx(0.5, abs=0.011)
    assert buf.clock_offset("F") == pytest.approx(2.0, abs=1e-6)
