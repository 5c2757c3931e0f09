"""The secure deployment survives a router restart without losing a batch, as real
processes on loopback, every one started with the TOML ``skyfuse certs`` wrote for it:
``skyfuse router --config router.toml`` (mutual TLS, the access policy), and its clients
``skyfuse fusion --config fusion-main.toml``, ``skyfuse record --config recorder.toml``,
``skyfuse sensor --config sensor-LYBE.toml``.

The router is killed (SIGKILL) while the sensor publishes and started again 4 s later on
the same port. The clients reconnect by themselves (no other process is restarted), and
the batches published while no router existed are recovered from the sensor's advanced
publisher cache by the fusion service and the recorder: their recovery queries and the
sensor's heartbeat pass the access policy (``radar/*/plots/@adv/**`` rules). Afterwards
``skyfuse tracks --config client-viewer.toml --snapshot`` reads the picture."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest
from service_support import last_payload, wait_for_router
from skyfuse.schemas import keys
from skyfuse.services.recording.mcap_io import iter_recording
from skyfuse.services.runtime import security
from skyfuse.services.runtime.transport import (
    Inbox,
    free_port,
    open_session,
    service_alive_key,
    transport_config,
    wait_for_tokens,
)

pytestmark = pytest.mark.service
OUTAGE_S = 4.0


def test_router_restart_loses_nothing_through_the_access_policy(start_skyfuse, tmp_path, until):
    d = tmp_path / "secure"
    ep = f"tls/127.0.0.1:{free_port()}"
    people = security.principals(["LYBE"], ["main"], ["recorder"], ["viewer"])
    security.write_deployment(d, people, ["localhost", "127.0.0.1"], router=ep)
    viewer = transport_config(toml_path=d / "client-viewer.toml")
    router = start_skyfuse("router", "--config", str(d / "router.toml"), log="router-1")
    wait_for_router(viewer)
    out, stats = tmp_path / "r.mcap", tmp_path / "stats.json"
    start_skyfuse("fusion", "--config", str(d / "fusion-main.toml"), "--status-interval", "0.5",
                  "--snapshot-interval", "off", log="fusion")  # fmt: skip
    rec = start_skyfuse("record", "--config", str(d / "recorder.toml"), "--out", str(out),
                        "--stats", str(stats), "--no-foxglove", log="recorder")  # fmt: skip
    with open_session(viewer) as s:
        status = Inbox()
        status.subscribe(s, keys.fusion_status("main"), "status")
        names = [service_alive_key("fusion"), service_alive_key("recorder")]
        assert wait_for_tokens(s, names, 30.0) == []
        sensor = start_skyfuse(
            "sensor", "--config", str(d / "sensor-LYBE.toml"), "--radar", "LYBE",
            "--scenario", "regional", "--param", "radars=3", "--targets", "8",
            "--duration", "64", "--speed", "4", "--resume-max-age", "off", log="sensor",
        )  # fmt: skip
        cycles = lambda: (last_payload(status, 0.6) or {}).get("counters", {}).get("cycles", 0)  # noqa: E731
        assert until(lambda: cycles() > 4, 30)
    router.send_signal(signal.SIGKILL)
    router.wait()
    time.sleep(OUTAGE_S)
    start_skyfuse("router", "--config", str(d / "router.toml"), log="router-2")
    wait_for_router(viewer)
    assert sensor.wait(timeout=60) == 0
    with open_session(viewer) as s:
        status = Inbox()
        status.subscribe(s, keys.fusion_status("main"), "status")
        final = {}

        def settled() -> bool:
            st = last_payload(status, 1.1) or {}
            final.update(st)
            r = next((r for r in st.get("radars", []) if r["radar_id"] == "LYBE"), None)
            return r is not None and st["counters"]["queued"] == 0 and r["batches"] >= 240

        until(settled, 30)
        snap = subprocess.run(
            [sys.executable, "-m", "skyfuse.services.cli", "tracks", "--config",
             str(d / "client-viewer.toml"), "--snapshot", "--json"],
            capture_output=True, timeout=60,
        )  # fmt: skip
    rec.send_signal(signal.SIGTERM)
    assert rec.wait(timeout=20) == 0
    recorded = [m.message.seq for m in iter_recording(out, [keys.radar_plots("LYBE")])]
    summary = json.loads(stats.read_text())
    lybe = next(r for r in final["radars"] if r["radar_id"] == "LYBE")
    print(json.dumps({"fusion": lybe, "recorded": len(recorded), "recorder": summary["rejected"],
                      "recorder_lost": summary.get("batches_lost")}))  # fmt: skip
    published = 256  # 64 s of the radar's data: 4 scans of 4 s × 16 sectors… per 16 s
    assert lybe["batches_lost"] == 0 and lybe["batches_refused"] == 0
    assert lybe["batches"] == len(recorded) == len(set(recorded)) == published
    assert not summary["batches_lost"]
    assert snap.returncode == 0, snap.stderr.decode()[-500:]
    assert json.loads(snap.stdout.decode().splitlines()[0])["topic"] == keys.fusion_snapshot("main")
