"""A restarted simulated sensor goes on at once (finding of the live probe: ``skyfuse
sensor --radar LYBE --scenario regional --speed 2 --state-dir D`` stopped with SIGTERM
and started again logged ``continuing after seq N`` and then published nothing for
about 135 s: the site event at the scenario start was not skipped and set the pacing
origin, so the first batch not yet published was due as late as the data already
published).

A sensor at ``--speed 8`` is stopped after about 100 s of data time (12 s of wall time),
started again with the same state directory: its first batch follows its site message
at once (well within one second; before, 12 s later) and continues the numbering exactly
(SIGTERM saved the progress)."""

from __future__ import annotations

import signal
import time

import pytest
from skyfuse.schemas import PlotBatch, keys
from skyfuse.services.runtime.transport import Inbox, TransportConfig, free_port, open_session

pytestmark = pytest.mark.service


def test_restarted_sensor_publishes_its_next_batch_at_once(start_skyfuse, tmp_path, until):
    ep = f"tcp/127.0.0.1:{free_port()}"
    args = (
        "sensor", "--radar", "LYBE", "--scenario", "regional", "--param", "radars=3",
        "--targets", "8", "--duration", "600", "--speed", "8", "--connect", ep,
        "--state-dir", str(tmp_path / "state"),
    )  # fmt: skip
    with open_session(TransportConfig(listen=[ep])) as s:
        inbox = Inbox()
        inbox.subscribe(s, keys.radar_plots("LYBE"), "plots")
        inbox.subscribe(s, keys.radar_site("LYBE"), "site")
        first = start_skyfuse(*args, log="sensor-1")
        last: list[int] = []

        def reached() -> bool:
            for item in inbox.drain(100_000):
                if item.tag == "plots":
                    last.append(PlotBatch.from_json_bytes(item.payload).seq)
            return bool(last) and last[-1] >= 400

        assert until(reached, 60)
        first.send_signal(signal.SIGTERM)
        assert first.wait(timeout=10) == 0
        time.sleep(0.5)
        reached()
        inbox.drain(100_000)
        second = start_skyfuse(*args, log="sensor-2")
        site_at = plots_at = None
        seq = None
        end = time.monotonic() + 40
        while plots_at is None and time.monotonic() < end:
            item = inbox.get(0.1)
            if item is None:
                continue
            if item.tag == "site" and site_at is None:
                site_at = time.monotonic()
            elif item.tag == "plots":
                plots_at, seq = time.monotonic(), PlotBatch.from_json_bytes(item.payload).seq
        second.send_signal(signal.SIGTERM)
        second.wait(timeout=10)
    assert site_at is not None and plots_at is not None, "the restarted sensor published no batch"
    print({"last_before": last[-1], "first_after": seq, "silence_s": round(plots_at - site_at, 2)})
    assert seq == last[-1] + 1  # the numbering continues exactly
    assert plots_at - site_at < 2.0  # not the data time already published, paced again
