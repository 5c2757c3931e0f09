"""The fusion service's payload encodings and queryables on real Zenoh sessions: the
feed and Status published as ``application/json;skyfuse.{Model}/1``; the Status
queryable answers like the snapshot queryable."""

from __future__ import annotations

import threading
import time

import pytest
import zenoh
from skyfuse.schemas import SCHEMA_VERSION, Status, keys
from skyfuse.services.fusion.server import make_pipeline_factory, serve
from skyfuse.services.fusion.service import FusionConfig, FusionCore
from skyfuse.services.runtime.transport import (
    TransportConfig,
    free_port,
    loopback_endpoint,
    open_session,
    payload_encoding,
    service_alive_key,
    wait_for_tokens,
)

pytestmark = pytest.mark.service


def test_payload_encoding_names_the_schema():
    assert str(payload_encoding(keys.fusion_tracks("main"))) == (
        f"application/json;skyfuse.TrackBatch/{SCHEMA_VERSION}"
    )
    assert (
        str(payload_encoding(keys.radar_plots("R1")))
        == f"application/json;skyfuse.PlotBatch/{SCHEMA_VERSION}"
    )
    assert payload_encoding(keys.radar_alive("R1")) == zenoh.Encoding.ZENOH_BYTES


def test_status_queryable_and_encodings():
    from skyfuse.fusion.tracker.config import TrackerConfig

    ep = loopback_endpoint(free_port())
    core = FusionCore(
        FusionConfig(fusion_id="q1", status_interval=0.2, frame_lat0=45, frame_lon0=20),
        make_pipeline_factory(TrackerConfig(), "q1"),
    )
    halt = threading.Event()
    with (
        open_session(TransportConfig(mode="peer", listen=[ep])) as s_fusion,
        open_session(TransportConfig(mode="peer", connect=[ep])) as s_client,
    ):
        seen = []
        sub = s_client.declare_subscriber(keys.fusion_status("q1"), seen.append)
        t = threading.Thread(target=serve, args=(s_fusion, core, halt))
        t.start()
        try:
            assert wait_for_tokens(s_client, [service_alive_key("fusion")], 10.0) == []
            replies = list(s_client.get(keys.fusion_status("q1"), timeout=3.0))
            ok = [r.ok for r in replies if r.ok is not None]
            assert len(ok) == 1 and str(ok[0].key_expr) == keys.fusion_status("q1")
            st = Status.from_json_bytes(ok[0].payload.to_bytes())
            assert st.service_id == "q1" and st.backlog is not None
            assert str(ok[0].encoding) == f"application/json;skyfuse.Status/{SCHEMA_VERSION}"
            deadline = time.monotonic() + 5
            while not seen and time.monotonic() < deadline:
                time.sleep(0.05)
            assert (
                seen
                and str(seen[0].encoding) == f"application/json;skyfuse.Status/{SCHEMA_VERSION}"
            )
            snap = [r for r in s_client.get(keys.fusion_snapshot("q1"), timeout=3.0)]
            assert len(snap) == 1 and snap[0].err is not None  # no tracks yet: an error reply
        finally:
            halt.set()
            t.join(10)
            sub.undeclare()
    assert not t.is_alive()
