"""Real network faults between a sensor and the fusion service, in network namespaces this
test creates (and always deletes): the sensor in one namespace, the fusion service and the
recorder in another, joined by a veth pair (10.231.x.1 ↔ 10.231.x.2); each process is a
real ``skyfuse`` command started with ``ip netns exec``.

* **partition**: the link is cut (veth down) for 5 s while the sensor publishes;
* **router restart**: every process is a Zenoh client of a ``skyfuse router`` (in the
  fusion's namespace); the router is killed and started again 3 s later; no other
  process is restarted;
* **loss and delay**: 10 % packet loss and 200 ms delay on the link (``tc netem``; skipped
  where the kernel has no netem).

Each measures, from the recording (the recorder records the sensor's and the fusion's
Status too): what the sensor published, what the fusion applied, refused (by reason) and
counted as lost, what was recorded (each batch once), and how long after the fault ended
the fusion had applied everything the sensor had published by then ("picture whole").
Needs root and ``ip``; skipped with the reason otherwise."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from skyfuse.schemas import PlotBatch, Status, keys
from skyfuse.services.recording.mcap_io import iter_recording

pytestmark = pytest.mark.service
ROOT = Path(__file__).resolve().parents[3]


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, check=check)


class Net:
    """Two namespaces (``sensor``, ``fusion``) joined by a veth pair."""

    def __init__(self, tag: str) -> None:
        n = os.getpid() % 200 + 20
        self.ns = {"sensor": f"sf-{tag}-s{os.getpid()}", "fusion": f"sf-{tag}-f{os.getpid()}"}
        self.addr = {"sensor": f"10.231.{n}.1", "fusion": f"10.231.{n}.2"}
        self.dev = {"sensor": f"sfs{os.getpid() % 100000}", "fusion": f"sff{os.getpid() % 100000}"}
        self.procs: list[subprocess.Popen] = []

    def create(self) -> None:
        for ns in self.ns.values():
            _ip("netns", "add", ns)
            _ip("-n", ns, "link", "set", "lo", "up")
        _ip("link", "add", self.dev["sensor"], "type", "veth", "peer", "name", self.dev["fusion"])
        for role, ns in self.ns.items():
            _ip("link", "set", self.dev[role], "netns", ns)
            _ip("-n", ns, "addr", "add", f"{self.addr[role]}/30", "dev", self.dev[role])
            _ip("-n", ns, "link", "set", self.dev[role], "up")

    def link(self, up: bool) -> None:
        for role, ns in self.ns.items():
            _ip("-n", ns, "link", "set", self.dev[role], "up" if up else "down")

    def netem(self, spec: list[str]) -> None:
        for role, ns in self.ns.items():
            r = subprocess.run(["ip", "netns", "exec", ns, "tc", "qdisc", "add", "dev",
                                self.dev[role], "root", "netem", *spec],
                               capture_output=True, text=True)  # fmt: skip
            if r.returncode != 0:
                pytest.skip(f"tc netem unavailable in this kernel: {r.stderr.strip()}")

    def start(self, role: str, log: Path, *args: str) -> subprocess.Popen:
        err = open(log, "wb")
        env = {**os.environ, "XDG_STATE_HOME": str(log.parent / f"state-{log.stem}")}
        cmd = ["ip", "netns", "exec", self.ns[role], sys.executable, "-m",
               "skyfuse.services.cli", *args]  # fmt: skip
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err, env=env, cwd=ROOT)
        err.close()
        self.procs.append(proc)
        return proc

    def delete(self) -> None:
        for proc in self.procs:
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        for proc in self.procs:
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        for ns in self.ns.values():  # deleting a namespace deletes its end of the veth
            _ip("netns", "del", ns, check=False)


@pytest.fixture
def net(request):
    if os.geteuid() != 0 or shutil.which("ip") is None:
        pytest.skip("network namespaces need root and iproute2's ip")
    probe = f"sf-probe-{os.getpid()}"
    r = _ip("netns", "add", probe, check=False)
    if r.returncode != 0:
        pytest.skip(f"cannot create a network namespace: {r.stderr.strip()}")
    _ip("netns", "del", probe, check=False)
    n = Net(request.node.name.split("[")[0][-6:].replace("_", ""))
    try:
        n.create()
        yield n
    finally:
        n.delete()


def _run(net: Net, tmp: Path, fault, *, router: bool = False, data_s: int = 48) -> dict:
    """Sensor (speed 4) → fusion + recorder; ``fault(net)`` runs once the fusion applies
    batches and returns the wall time the fault ended. The measures (module docstring)."""
    port = 7447
    fusion_ep = f"tcp/{net.addr['fusion']}:{port}"
    out = tmp / "r.mcap"
    if router:
        net.start("fusion", tmp / "router.log", "router", "--listen", fusion_ep)
        time.sleep(1.0)
        to = ["--mode", "client", "--connect", fusion_ep]
        fusion_args, rec_args, sensor_args = to, to, to
    else:
        fusion_args = ["--listen", fusion_ep]  # the recorder listens too: peers gossip
        rec_args = ["--connect", fusion_ep, "--listen", f"tcp/{net.addr['fusion']}:{port + 1}"]
        sensor_args = ["--connect", fusion_ep]
    net.start("fusion", tmp / "fusion.log", "fusion", *fusion_args, "--status-interval", "0.5",
              "--snapshot-interval", "off")  # fmt: skip
    net.start("fusion", tmp / "recorder.log", "record", "--out", str(out), "--no-foxglove",
              "--flush-interval", "0.2", "--stats", str(tmp / "stats.json"), *rec_args)  # fmt: skip
    sensor = net.start(
        "sensor", tmp / "sensor.log", "sensor", "--radar", "LYBE", "--scenario", "regional",
        "--param", "radars=3", "--targets", "8", "--duration", str(data_s), "--speed", "4",
        "--resume-max-age", "off", "--status-interval", "0.5", "--wait-for", "fusion,recorder",
        "--wait-timeout", "60", *sensor_args,
    )  # fmt: skip
    _wait_log(tmp / "fusion.log", "system frame", 60)
    time.sleep(1.5)
    healed = fault(net)
    assert sensor.wait(timeout=90) == 0, (tmp / "sensor.log").read_text()[-2000:]
    time.sleep(4.0)
    for proc in net.procs[::-1]:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            proc.wait(timeout=15)
    return _measures(out, json.loads((tmp / "stats.json").read_text()), healed)


def _wait_log(path: Path, text: str, timeout: float) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if path.exists() and text in path.read_text(errors="replace"):
            return
        time.sleep(0.2)
    raise AssertionError(f"{path.name}: no {text!r} after {timeout} s")


def _measures(out: Path, stats: dict, healed: float) -> dict:
    sensor, fusion, seqs = [], [], []
    for m in iter_recording(out):
        if m.topic == keys.service_status("sensor-LYBE"):
            sensor.append(Status.from_json_bytes(m.data))
        elif m.topic == keys.fusion_status("main"):
            fusion.append(Status.from_json_bytes(m.data))
        elif m.topic == keys.radar_plots("LYBE"):
            seqs.append(PlotBatch.from_json_bytes(m.data).seq)
    published = sensor[-1].counters["batches"]
    at_heal = max(s.counters["batches"] for s in sensor if s.time <= healed * 1e9)

    def accounted(st: Status) -> int:
        r = next((r for r in st.radars if r.radar_id == "LYBE"), None)
        return 0 if r is None else r.batches + r.batches_refused + r.batches_lost

    whole = next((st.time / 1e9 - healed for st in fusion
                  if st.time >= healed * 1e9 and accounted(st) >= at_heal), None)  # fmt: skip
    last = next(r for r in fusion[-1].radars if r.radar_id == "LYBE")
    return {
        "published": published,
        "applied": last.batches,
        "refused": last.batches_refused,
        "refused_by_reason": fusion[-1].rejected,
        "lost": last.batches_lost,
        "zenoh_missed": last.samples_missed,
        "recorded": len(seqs),
        "recorded_twice": len(seqs) - len(set(seqs)),
        "recorder_lost": stats["batches_lost"],
        "whole_after_s": None if whole is None else round(whole, 2),
    }


def test_a_five_second_partition(net, tmp_path):
    def cut(n: Net) -> float:
        n.link(False)
        time.sleep(5.0)
        n.link(True)
        return time.time()

    m = _run(net, tmp_path, cut)
    print(json.dumps({"partition_5s": m}))
    assert m["applied"] + m["refused"] + m["lost"] == m["published"]
    assert (
        m["recorded_twice"] == 0
        and m["recorded"] + sum(m["recorder_lost"].values()) == (m["published"])
    )
    assert m["lost"] == 0 and m["recorded"] == m["published"]  # within the cache depth
    assert m["whole_after_s"] is not None and m["whole_after_s"] < 4.0  # one scan (4 s)


def test_a_router_restart(net, tmp_path):
    def restart(n: Net) -> float:
        router = n.procs[0]
        router.send_signal(signal.SIGKILL)
        router.wait()
        time.sleep(3.0)
        ep = f"tcp/{n.addr['fusion']}:7447"
        n.start("fusion", tmp_path / "router-2.log", "router", "--listen", ep)
        return time.time()

    m = _run(net, tmp_path, restart, router=True)
    print(json.dumps({"router_restart_3s": m}))
    assert m["applied"] + m["refused"] + m["lost"] == m["published"]
    assert m["recorded_twice"] == 0 and m["lost"] == 0 and m["recorded"] == m["published"]
    assert m["whole_after_s"] is not None


def test_ten_percent_loss_and_200_ms_delay(net, tmp_path):
    net.netem(["loss", "10%", "delay", "200ms"])  # skips where netem is missing

    def nothing(n: Net) -> float:
        time.sleep(5.0)
        return time.time()

    m = _run(net, tmp_path, nothing)
    print(json.dumps({"loss_10pct_delay_200ms": m}))
    assert m["applied"] + m["refused"] + m["lost"] == m["published"]
    assert m["recorded_twice"] == 0
