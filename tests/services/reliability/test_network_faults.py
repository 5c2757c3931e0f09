"""Real network faults between a sensor and the fusion service, in network namespaces this
test creates (and always deletes): the sensor in one namespace, the fusion service and the
recorder in another, joined by a veth pair (10.231.x.1 ↔ 10.231.x.2); each process is a
real ``skyfuse`` command started with ``ip netns exec`` (``tests/netns_support.py``).

* **partition**: the link is cut (veth down) for 5 s while the sensor publishes;
* **router restart**: every process is a Zenoh client of a ``skyfuse router`` (in the
  fusion's namespace); the router is killed and started again 3 s later; no other
  process is restarted;
* **loss and delay**: 10 % packet loss and 200 ms delay on the link for the whole run,
  every process a client of a router in the fusion's namespace: ``tc netem`` where the
  kernel has it, else iptables' random drop on both ends of the veth and a delaying TCP
  relay on the sensor's route (an emulation: ``netns_support``); skipped with the reason
  when neither works.

Each measures, from the recording (the recorder records the sensor's and the fusion's
Status too): what the sensor published, what the fusion applied, refused (by reason) and
counted as lost, what was recorded (each batch once), and how long after the fault ended
(for a lasting fault: after the sensor's last batch) the fusion had applied everything the
sensor had published by then ("picture whole"); and the lag: for each sensor Status, the
time until a fusion Status accounts for the batches it counts (p50, max).
Needs root and ``ip``; skipped with the reason otherwise."""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path

import pytest
from netns_support import Net, namespaces_or_skip, tag_of
from skyfuse.schemas import PlotBatch, Status, keys
from skyfuse.services.recording.mcap_io import iter_recording

pytestmark = pytest.mark.service


@pytest.fixture
def net(request):
    namespaces_or_skip()
    n = Net(tag_of(request.node.name))
    try:
        n.create()
        yield n
    finally:
        n.delete()


def _run(
    net: Net, tmp: Path, fault, *, router: bool = False, data_s: int = 48, sensor_ep=None
) -> dict:
    """Sensor (speed 4) → fusion + recorder; ``fault(net)`` runs once the fusion applies
    batches and returns the wall time the fault ended (``None``: it lasts). The sensor
    connects to ``sensor_ep`` if given (a relay). The measures (module docstring)."""
    port = 7447
    fusion_ep = f"tcp/{net.addr['fusion']}:{port}"
    out = tmp / "r.mcap"
    if router:
        net.start("fusion", tmp / "router.log", "router", "--listen", fusion_ep)
        time.sleep(1.0)
        to = ["--mode", "client", "--connect", fusion_ep]
        fusion_args, rec_args, sensor_args = to, to, to
        if sensor_ep is not None:
            sensor_args = ["--mode", "client", "--connect", sensor_ep]
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
    net.stop_all()
    return _measures(out, json.loads((tmp / "stats.json").read_text()), healed)


def _wait_log(path: Path, text: str, timeout: float) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if path.exists() and text in path.read_text(errors="replace"):
            return
        time.sleep(0.2)
    raise AssertionError(f"{path.name}: no {text!r} after {timeout} s")


def _measures(out: Path, stats: dict, healed: float | None) -> dict:
    sensor, fusion, seqs = [], [], []
    for m in iter_recording(out):
        if m.topic == keys.service_status("sensor-LYBE"):
            sensor.append(Status.from_json_bytes(m.data))
        elif m.topic == keys.fusion_status("main"):
            fusion.append(Status.from_json_bytes(m.data))
        elif m.topic == keys.radar_plots("LYBE"):
            seqs.append(PlotBatch.from_json_bytes(m.data).seq)
    published = sensor[-1].counters["batches"]
    if healed is None:  # a lasting fault: from the sensor's last batch
        healed = next(s.time for s in sensor if s.counters["batches"] == published) / 1e9
    at_heal = max(s.counters["batches"] for s in sensor if s.time <= healed * 1e9)
    whole = _whole_after(fusion, healed, at_heal)
    lags = [_whole_after(fusion, s.time / 1e9, s.counters["batches"]) for s in sensor]
    lags = sorted(x for x in lags if x is not None)
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
        "lag_s": {"p50": round(lags[len(lags) // 2], 2), "max": round(lags[-1], 2)}
        if lags
        else None,
        "latency_ms_p50": fusion[-1].latency_ms.p50 if fusion[-1].latency_ms else None,
    }


def _accounted(st: Status) -> int:
    r = next((r for r in st.radars if r.radar_id == "LYBE"), None)
    return 0 if r is None else r.batches + r.batches_refused + r.batches_lost


def _whole_after(fusion: list[Status], t: float, n: int) -> float | None:
    """Seconds after ``t`` until a fusion Status accounts for ``n`` batches (None: never)."""
    return next((st.time / 1e9 - t for st in fusion
                 if st.time >= t * 1e9 and _accounted(st) >= n), None)  # fmt: skip


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
    relay_ep = None
    no_netem = net.netem(10, 200)
    if no_netem is not None:  # no netem: iptables drops, a relay delays (netns_support)
        err = net.iptables_loss(0.1)
        if err is not None:
            pytest.skip(f"no netem ({no_netem}) and no iptables loss ({err})")
        router_ep = f"{net.addr['fusion']}:7447"
        net.relay("sensor", tmp_path / "relay.log", "127.0.0.1:7500", router_ep, 0.2)
        relay_ep = "tcp/127.0.0.1:7500"

    m = _run(net, tmp_path, lambda n: None, router=True, sensor_ep=relay_ep)
    m["emulation"] = "tc netem" if no_netem is None else "iptables loss + delaying relay"
    if no_netem is not None:
        m["link_packets"] = net.iptables_counts()
        m["relay"] = json.loads((tmp_path / "relay.json").read_text())
    print(json.dumps({"loss_10pct_delay_200ms": m}))
    assert m["applied"] + m["refused"] + m["lost"] == m["published"]
    assert m["recorded_twice"] == 0
    assert m["recorded"] + sum(m["recorder_lost"].values()) == m["published"]
    assert m["whole_after_s"] is not None
    if no_netem is not None:  # the fault was on the path: packets dropped, the relay used
        pk = m["link_packets"]  # binomial: the dropped fraction within 5 sigma of 10 %
        sigma = (0.1 * 0.9 / max(pk["packets"], 1)) ** 0.5
        assert pk["packets"] > 100 and abs(pk["dropped"] / pk["packets"] - 0.1) < 5 * sigma, pk
        assert m["relay"]["connections"] >= 1 and m["relay"]["bytes_to"] > 0
