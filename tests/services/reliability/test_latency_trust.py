"""Latency figures come from trusted clocks only (finding of the live probe: without the
sender's wall-clock attachment, the fusion service took the batch's own ``time_end`` as
the send time, so a foreign publisher set Status ``latency_ms.p99`` to 2.9·10¹⁰ ms).

A batch without the stamp, or with a stamp no clock could give (in the future, or more
than an hour old), is applied like any other but left out of the latency figures and
counted (``latency_ms.unstamped`` / ``implausible``). The figures of the stamped batches
are the publication time minus the stamp: checked against the stamps sent."""

from __future__ import annotations

import time

import numpy as np
import pytest
from service_support import make_batch, make_site
from skyfuse.services.fusion.service import FusionConfig, FusionCore


class _Pipeline:
    """Applies every batch: one output message per group (the latency path only)."""

    def __init__(self, frame) -> None:
        self.rejected: dict = {}
        self.frame = frame

    def process_parts(self, items, **kw):
        from types import SimpleNamespace

        yield SimpleNamespace(
            message=SimpleNamespace(header={}), events=[], failed=[], applied=[b for _, b in items]
        )

    def full(self):
        return None


def test_unstamped_and_impossible_stamps_stay_out_of_the_latency():
    cfg = FusionConfig(sites=[make_site("R1", 45.0, 20.0)], future_tolerance=None,
                       reorder_wait=0.0, frame_lat0=45.0, frame_lon0=20.0)  # fmt: skip
    core = FusionCore(cfg, _Pipeline)
    rng = np.random.default_rng(4)
    now = time.time_ns()
    stamps = [
        now - 200_000_000,  # 200 ms ago: counted
        None,  # no stamp (a foreign publisher, an old recording): the old code used time_end
        now + 3_600_000_000_000,  # an hour ahead of this host's clock
        now - 7_200_000_000_000,  # two hours old
        now - 100_000_000,
    ]
    for seq, stamp in enumerate(stamps):
        b = make_batch("R1", seq // 4, seq % 4, 4, 3, rng)
        assert core.on_plots(b, 0.0, stamp)
        for out in core.poll(flush=True):
            core.published(out)
    lat = core.latency_stats()
    assert lat.count == 2  # the two batches with a plausible stamp
    assert lat.max == pytest.approx(200.0, abs=(time.time_ns() - now) / 1e6 + 1.0)
    assert 100.0 <= lat.p50 < 100.0 + (time.time_ns() - now) / 1e6 + 200.0
    assert (lat.unstamped, lat.implausible) == (1, 2)
