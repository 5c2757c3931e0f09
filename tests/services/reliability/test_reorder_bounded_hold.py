"""Every batch leaves the reorder buffer within ``max_hold`` (finding of the live probe: a
batch whose ``time_end`` was later than the radars' data, but within ``now +
future_tolerance``, was never released while other batches kept arriving in front of it;
``oldest_wait_s`` grew without bound, ``behind`` stayed set, and SIGTERM overran the
shutdown: forced exit, the last seconds of state not saved).

* In the core: a radar replaying old data at 4 batches/s and one message dated just
  inside the clock tolerance (from another radar with a site). The message is settled
  within ``max_hold`` — refused as ``ahead of the data``, since everything received since
  is far behind it — and never moves the service time; the radar's batches keep being
  applied; the backlog's oldest wait stays bounded. A radar genuinely ahead of a lagging
  one is released within ``max_hold`` (the lagging radar's batches then come too late:
  counted); a radar's own stream is never refused.
* As processes: ``skyfuse fusion`` with that message in its buffer stops on SIGTERM with
  exit code 0 within its deadline and saves its state on the way out.
"""

from __future__ import annotations

import json
import signal
import time
from types import SimpleNamespace

import numpy as np
import pytest
from service_support import make_batch, make_site
from skyfuse.schemas import PlotBatch, keys
from skyfuse.services.fusion.service import FusionConfig, FusionCore
from skyfuse.services.runtime.transport import (
    Inbox,
    TransportConfig,
    declare_publisher,
    free_port,
    open_session,
    service_alive_key,
    wait_for_tokens,
    wall_stamp,
)

S = 1_000_000_000


class _Pipeline:
    """Applies every batch it is given; remembers them (no tracker)."""

    def __init__(self, frame) -> None:
        self.rejected: dict = {}
        self.applied: list[PlotBatch] = []

    def process_parts(self, items, **kw):
        self.applied += [b for _, b in items]
        yield SimpleNamespace(
            message=SimpleNamespace(header={}), events=[], failed=[], applied=[b for _, b in items]
        )

    def full(self):
        return None

    def picture(self):
        return _Picture()


class _Picture(list):
    confirmed = ()


def _core(**kw) -> tuple[FusionCore, list[_Pipeline]]:
    made: list[_Pipeline] = []

    def factory(frame):
        made.append(_Pipeline(frame))
        return made[-1]

    sites = [make_site("R1", 45.0, 20.0), make_site("R2", 45.3, 20.0), make_site("R9", 45.1, 20.2)]
    cfg = FusionConfig(sites=sites, frame_lat0=45.0, frame_lon0=20.0, **kw)
    return FusionCore(cfg, factory), made


def _stream(radar: str, n: int, t0: int, epoch: int = 3) -> list[PlotBatch]:
    """``n`` batches of ``radar``, 0.25 s apart in data time from ``t0`` (ns)."""
    rng = np.random.default_rng(len(radar) + n)
    out = []
    for k in range(n):
        b = make_batch(radar, k // 16, k % 16, 16, 2, rng)
        shift = t0 + k * S // 4 - b.time_end
        out.append(b.model_copy(update={
            "seq": k, "epoch": epoch, "time_start": b.time_start + shift,
            "time_end": b.time_end + shift, "time": [t + shift for t in b.time],
        }))  # fmt: skip
    return out


def test_a_message_ahead_of_old_data_leaves_within_max_hold_and_moves_nothing():
    core, made = _core(reorder_wait=0.5, max_hold=3.0, future_tolerance=1.0)
    wall0 = time.time_ns()
    old = _stream("R1", 200, wall0 - 30 * 86_400 * S)  # a replay of data 30 days old
    poison = _stream("R9", 1, wall0 + S // 2)[0]  # inside the tolerance of the wall clock
    oldest = []
    for k, b in enumerate(old):
        now = 0.25 * k  # the arrival clock, s
        assert core.on_plots(b, now, recv_ns=wall0 + k * S // 4)
        if k == 10:
            assert core.on_plots(poison, now, recv_ns=wall0 + k * S // 4)
        core.poll(now)
        oldest.append(core.backlog(now).oldest_wait_s)
    assert core.rejected.get("ahead of the data") == 1
    assert max(oldest) <= 3.0 + 0.25  # bounded by max_hold (one step of the clock)
    assert not core.backlog(0.25 * 199).behind
    assert poison not in made[0].applied
    assert core.buffer.last_time < wall0  # the service time never jumped to the poison
    assert len(made[0].applied) >= 200 - 3  # the radar's batches go on (the last still held)
    r9 = next(r for r in core.status().radars if r.radar_id == "R9")
    assert (r9.batches, r9.batches_refused) == (0, 1)


def test_a_radar_ahead_of_a_lagging_one_is_released_within_max_hold():
    core, made = _core(reorder_wait=0.5, max_hold=3.0, future_tolerance=None, max_lateness=2.0)
    t0 = 1_700_000_000 * S
    ahead, lagging = _stream("R2", 120, t0 + 10 * S), _stream("R1", 120, t0)
    waits = []
    for k in range(120):
        now = 0.25 * k
        assert core.on_plots(ahead[k], now)
        core.on_plots(lagging[k], now)  # refused as too late once R2 is applied: counted
        core.poll(now)
        waits.append(core.backlog(now).oldest_wait_s)
    assert max(waits) <= 3.0 + 0.25
    assert len([b for b in made[0].applied if b.radar_id == "R2"]) >= 120 - 3
    assert core.rejected.get("too late", 0) > 0 and "ahead of the data" not in core.rejected


@pytest.mark.service
def test_fusion_stops_within_its_deadline_and_saves_with_a_poison_batch_queued(
    start_skyfuse, tmp_path, until
):
    ep = f"tcp/127.0.0.1:{free_port()}"
    state = tmp_path / "state"
    with open_session(TransportConfig(listen=[ep])) as s:
        status = Inbox()
        status.subscribe(s, keys.fusion_status("main"), "status")
        fusion = start_skyfuse(
            "fusion", "--connect", ep, "--status-interval", "0.5", "--state-dir", str(state),
            "--snapshot-interval", "1", log="fusion",
        )  # fmt: skip
        assert wait_for_tokens(s, [service_alive_key("fusion")], 30.0) == []
        sensor = start_skyfuse(
            "sensor", "--radar", "LYBE", "--scenario", "regional", "--param", "radars=3",
            "--targets", "8", "--duration", "400", "--speed", "4", "--connect", ep,
            "--resume-max-age", "off", log="sensor",
        )  # fmt: skip
        seen = {}

        def applied() -> bool:
            item = status.get(0.6)
            if item is not None:
                seen.update(json.loads(item.payload))
            return seen.get("counters", {}).get("cycles", 0) > 8

        assert until(applied, 40)
        poison = _stream("R9", 1, time.time_ns() + S // 2)[0]
        site_pub = declare_publisher(s, keys.radar_site("R9"))
        site_pub.put(make_site("R9", 44.9, 20.4).to_json_bytes())
        time.sleep(0.3)
        declare_publisher(s, keys.radar_plots("R9")).put(
            poison.to_json_bytes(), attachment=wall_stamp()
        )
        waits = []
        end = time.monotonic() + 8.0
        while time.monotonic() < end:
            item = status.get(0.6)
            if item is not None:
                st = json.loads(item.payload)
                waits.append(st["backlog"]["oldest_wait_s"])
                refused = st["rejected"].get("ahead of the data", 0)
        t_stop = time.time()
        fusion.send_signal(signal.SIGTERM)
        rc = fusion.wait(timeout=15)
        took = time.time() - t_stop
        sensor.send_signal(signal.SIGTERM)
        sensor.wait(timeout=15)
    saved = (state / "fusion-main" if (state / "fusion-main").is_dir() else state).glob("*")
    newest = max((p.stat().st_mtime for p in saved if p.is_file()), default=0.0)
    print(json.dumps({"oldest_wait_s": max(waits), "refused": refused, "rc": rc,
                      "stop_s": round(took, 2), "state_after_stop": newest >= t_stop}))  # fmt: skip
    assert max(waits) < 5.0 and refused == 1
    assert rc == 0 and newest >= t_stop
