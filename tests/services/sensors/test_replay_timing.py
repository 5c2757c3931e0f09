"""Replay timing (services.sensors.replay): the time origin is the recording's first site
or plots message of any radar, so replays of different radars of one file, started
together, publish each batch at the same wall time after their start as one replay of
every radar would."""

from __future__ import annotations

import time

import numpy as np
from service_support import EPOCH, make_batch, make_site
from skyfuse.schemas import keys
from skyfuse.services.recording.mcap_io import RecordingWriter
from skyfuse.services.sensors import replay as replay_mod

SPEED = 4.0


class _Pub:
    def __init__(self, log, topic):
        self.log, self.topic = log, topic
        self.matching_status = type("M", (), {"matching": False})()

    def put(self, data, attachment=None):
        self.log.append((time.monotonic(), self.topic))

    def undeclare(self):
        pass


def _recording(path):
    """R1 from EPOCH; R2's site and batches only from EPOCH + 2 s (its first sector)."""
    rng = np.random.default_rng(0)
    with RecordingWriter(path, metadata={"command": "test"}) as w:
        w.write(keys.radar_site("R1"), make_site("R1", 45.0, 20.0), EPOCH)
        w.write(keys.radar_site("R2"), make_site("R2", 45.2, 20.0), EPOCH + 2_000_000_000)
        for sector in range(4):
            for r in ("R1", "R2"):
                b = make_batch(r, 0, sector, 4, 3, rng)
                if r == "R2" and b.time_end < EPOCH + 2_000_000_000:
                    continue
                w.write(keys.radar_plots(r), b, b.time_end)


def _publish_times(monkeypatch, path, radars, start_at=None):
    """Monotonic times of each plots publication of a replay of ``radars``, with topics."""
    log = []
    monkeypatch.setattr(replay_mod, "declare_publisher", lambda s, topic: _Pub(log, topic))
    monkeypatch.setattr(
        replay_mod, "declare_cached_publisher", lambda s, topic, cache: _Pub(log, topic)
    )
    monkeypatch.setattr(replay_mod, "declare_liveliness", lambda s, key: _Pub([], key))
    replay_mod.replay(None, path, speed=SPEED, radars=radars, start_at=start_at)
    return [(t, topic) for t, topic in log if topic.endswith("/plots")]


def _publish_offsets(monkeypatch, path, radars):
    """Seconds from the call to each plots publication of a replay of ``radars``."""
    t0 = time.monotonic()
    return [(t - t0, topic) for t, topic in _publish_times(monkeypatch, path, radars)]


def test_replays_of_single_radars_keep_the_recording_phase(tmp_path, monkeypatch):
    path = tmp_path / "two.mcap"
    _recording(path)
    assert replay_mod.replay_start(path, replay_mod.REPLAYED_KINDS) == EPOCH
    both = _publish_offsets(monkeypatch, path, None)
    only_r2 = _publish_offsets(monkeypatch, path, {"R2"})
    r2_in_both = [t for t, topic in both if topic == keys.radar_plots("R2")]
    assert len(only_r2) == len(r2_in_both) == 3
    # R2's batches end 2, 3 and 4 s into the file: published (2, 3, 4) s / SPEED after the
    # start, alone as in the replay of both radars (before the fix 2 s / SPEED earlier:
    # the origin was R2's own site, 2 s into the file)
    for k, ((t_alone, _), t_both) in enumerate(zip(only_r2, r2_in_both)):
        assert (2.0 + k) / SPEED - 0.01 <= t_alone < (2.0 + k) / SPEED + 0.2
        assert abs(t_alone - t_both) < 0.2


def _offsets_from(monkeypatch, path, radars, start_at):
    """Seconds from ``start_at`` (Unix time) to each plots publication."""
    mono_start = time.monotonic() + (start_at - time.time())
    return [t - mono_start for t, _ in _publish_times(monkeypatch, path, radars, start_at)]


def test_start_at_puts_every_replay_on_one_clock(tmp_path, monkeypatch):
    """``start_at`` (Unix time): R1's batches end 1, 2, 3, 4 s into the file, so they are
    due at start_at + (1, 2, 3, 4) s / SPEED whenever the replay itself begins; a start in
    the past publishes what is already due at once, then keeps the same clock."""
    path = tmp_path / "two.mcap"
    _recording(path)
    got = _offsets_from(monkeypatch, path, {"R1"}, time.time() + 0.4)
    assert len(got) == 4
    for k, t in enumerate(got):
        assert (1.0 + k) / SPEED - 0.01 <= t < (1.0 + k) / SPEED + 0.2
    # R1's first two batches (due at 0.25 and 0.5 s) are already due
    got = _offsets_from(monkeypatch, path, {"R1"}, time.time() - 0.6)
    assert got[0] < 0.7 and got[1] < 0.7  # at once
    assert 0.75 - 0.01 <= got[2] < 0.95 and 1.0 - 0.01 <= got[3] < 1.2


def test_sensor_replay_takes_start_at_and_align(tmp_path, monkeypatch):
    """``skyfuse sensor --replay FILE --radar ID`` maps the recording's start to
    ``--start-at`` (or the next ``--align`` multiple), like the simulated sensor."""
    from skyfuse.services.cli import cmd_sensor
    from skyfuse.services.sensors.config import SensorServiceConfig

    path = tmp_path / "two.mcap"
    _recording(path)
    seen = {}

    def fake_replay(session, file, **kw):
        seen.update(kw)
        return replay_mod.ReplayResult(published={keys.radar_plots("R1"): 1})

    monkeypatch.setattr(replay_mod, "replay", fake_replay)
    monkeypatch.setattr(cmd_sensor, "declare_liveliness", lambda s, key: _Pub([], key))
    monkeypatch.setattr(cmd_sensor, "_waited", lambda session, cfg, stop: True)
    cfg = SensorServiceConfig(radar="R1", replay=path, start_at=1_800_000_000.5)
    assert cmd_sensor._replay(None, cfg, None) == 0
    assert seen["start_at"] == 1_800_000_000.5 and seen["radars"] == {"R1"}
    cfg = SensorServiceConfig(radar="R1", replay=path, align=10.0)
    before = time.time()
    assert cmd_sensor._replay(None, cfg, None) == 0
    assert seen["start_at"] % 10.0 == 0.0 and before + 1.0 <= seen["start_at"] <= before + 11.0
