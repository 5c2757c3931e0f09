"""``kill -9`` of a ``skyfuse fusion`` process under replayed input (a simulated 3-radar
recording replayed at twice real time), then a restart with the same state directory:
the new incarnation (``epoch`` 2) resumes the saved tracks with the same ids — the same
aircraft (positions continue within what a 350 m/s target can fly) — its cycles continue,
and every id it creates is new (above every id of the first incarnation). Figures
(restart time, data-time gap) are printed, never asserted."""

from __future__ import annotations

import json
import time

import pytest
from pyproj import Geod
from skyfuse.schemas import FeedKind, TrackBatch, TrackPicture, keys
from skyfuse.services.runtime.transport import (
    Inbox,
    TransportConfig,
    free_port,
    open_session,
    service_alive_key,
    wait_for_tokens,
)

pytestmark = pytest.mark.service
GEOD = Geod(ellps="WGS84")


def collect(inbox: Inbox, msgs: list, until, timeout: float) -> bool:
    """Append ``(receive time, TrackBatch)`` to ``msgs`` until ``until(msgs)``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        item = inbox.get(timeout=0.1)
        if item is not None:
            msgs.append((time.monotonic(), TrackBatch.from_json_bytes(item.payload)))
            if until(msgs):
                return True
    return False


def test_kill_9_fusion_resumes_the_same_track_ids(start_skyfuse, simulated_recording, tmp_path):
    rec = simulated_recording(
        "--scenario", "regional", "--seed", "3", "--duration", "70", "--param", "radars=3"
    )
    ep = f"tcp/127.0.0.1:{free_port()}"
    fusion_args = (
        "fusion", "--connect", ep, "--state-dir", str(tmp_path / "state"),
        "--snapshot-interval", "0.5", "--reorder-wait", "0.2", "--future-tolerance", "off",
    )  # fmt: skip
    with open_session(TransportConfig(listen=[ep])) as s:
        inbox = Inbox()
        inbox.subscribe(s, keys.fusion_tracks("main"), "tracks")
        first = start_skyfuse(*fusion_args, log="fusion-1")
        assert wait_for_tokens(s, [service_alive_key("fusion")], 30.0) == []
        start_skyfuse("replay", str(rec), "--speed", "2", "--connect", ep, log="replay")
        before: list = []
        confirmed = lambda m: m[-1][1].kind is FeedKind.FULL and len(m[-1][1].tracks) >= 12  # noqa: E731
        assert collect(inbox, before, confirmed, 40.0), "no picture of 12 tracks"
        collect(inbox, before, lambda m: False, 1.5)  # a snapshot or two more
        first.kill()  # SIGKILL
        first.wait()
        t_kill = time.monotonic()
        second = start_skyfuse(*fusion_args, log="fusion-2")
        after: list = []
        new_full = lambda m: m[-1][1].epoch == 2 and m[-1][1].kind is FeedKind.FULL  # noqa: E731
        assert collect(inbox, after, new_full, 30.0), "the restarted service published no picture"
        collect(inbox, after, lambda m: False, 3.0)
        assert second.poll() is None
    old = [m for _, m in before + after if m.epoch == 1]
    new = [(t, m) for t, m in after if m.epoch == 2]
    assert {m.epoch for _, m in before} == {1} and new
    pic = TrackPicture()
    for m in old:
        pic.apply(m)
    last_old = {i: t for i, t in pic.tracks.items()}
    t_first, f2 = next((t, m) for t, m in new if m.kind is FeedKind.FULL)
    resumed = {t.track_id: t for t in f2.tracks}
    common = set(last_old) & set(resumed)
    assert len(common) >= 0.8 * len(last_old), (len(common), len(last_old))
    assert f2.cycle > 1  # cycles continue from the snapshot
    # an id of the first incarnation seen again is the same aircraft (no id reused for
    # another one): its first row after the restart continues its last row before
    last_row = {t.track_id: t for m in old for t in m.tracks}
    first_row: dict = {}
    for _, m in new:
        for t in m.tracks:
            first_row.setdefault(t.track_id, t)
    again = set(last_row) & set(first_row)
    assert again >= common
    for i in again:
        a, b = last_row[i], first_row[i]
        dist = GEOD.inv(a.lon, a.lat, b.lon, b.lat)[2]
        assert dist <= 350.0 * abs(b.time - a.time) / 1e9 + 2000.0, (i, dist)
    new_ids = set(first_row) - set(last_row)
    gap = (f2.time - max(m.time for m in old)) / 1e9
    print(
        json.dumps(
            {
                "restart_to_first_picture_s": round(t_first - t_kill, 2),
                "data_gap_s": round(gap, 2),
                "tracks_before": len(last_old),
                "resumed_same_id": len(common),
                "new_ids_after": len(new_ids),
            }
        )
    )
