"""Network namespaces for the network fault tests: two namespaces (``sensor``, ``fusion``)
joined by a veth pair, real ``skyfuse`` processes started in them with ``ip netns exec``,
and the faults put on the link: cut (veth down), packet loss and delay.

**Loss and delay.** ``tc netem`` is the first choice (loss and delay of the packets on both
ends of the veth). Where the kernel has no netem ("Specified qdisc kind is unknown"), the
loss is ``iptables -m statistic --mode random --probability P -j DROP`` on the packets
leaving each end of the veth (both directions, as netem on both ends), and the delay a
:mod:`delay_relay` in the sensor's namespace on the sensor's route to the fusion side: each
direction of the byte stream is held ``delay`` s. That is an emulation, not netem: the
TCP connection that crosses the lossy link is the relay's, whose round trip is the veth's
(≈ 0.1 ms) instead of 2 × delay, so it recovers a lost segment sooner than it would on a
real link with that delay; the applications on both ends see the delay and the loss's
retransmission stalls.

Everything a :class:`Net` creates is deleted by :meth:`Net.delete` (deleting a namespace
deletes its end of the veth and its iptables rules)."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RELAY = Path(__file__).resolve().parent / "delay_relay.py"


def ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, check=check)


def namespaces_or_skip() -> None:
    """Skip (with the reason) where network namespaces cannot be made."""
    if os.geteuid() != 0 or shutil.which("ip") is None:
        pytest.skip("network namespaces need root and iproute2's ip")
    probe = f"sf-probe-{os.getpid()}"
    r = ip("netns", "add", probe, check=False)
    if r.returncode != 0:
        pytest.skip(f"cannot create a network namespace: {r.stderr.strip()}")
    ip("netns", "del", probe, check=False)


class Net:
    """Two namespaces (``sensor``, ``fusion``) joined by a veth pair (10.231.n.1 ↔ .2)."""

    def __init__(self, tag: str) -> None:
        n = os.getpid() % 200 + 20
        self.ns = {"sensor": f"sf-{tag}-s{os.getpid()}", "fusion": f"sf-{tag}-f{os.getpid()}"}
        self.addr = {"sensor": f"10.231.{n}.1", "fusion": f"10.231.{n}.2"}
        self.dev = {"sensor": f"sfs{os.getpid() % 100000}", "fusion": f"sff{os.getpid() % 100000}"}
        self.procs: list[subprocess.Popen] = []

    def create(self) -> None:
        for ns in self.ns.values():
            ip("netns", "add", ns)
            ip("-n", ns, "link", "set", "lo", "up")
        ip("link", "add", self.dev["sensor"], "type", "veth", "peer", "name", self.dev["fusion"])
        for role, ns in self.ns.items():
            ip("link", "set", self.dev[role], "netns", ns)
            ip("-n", ns, "addr", "add", f"{self.addr[role]}/30", "dev", self.dev[role])
            ip("-n", ns, "link", "set", self.dev[role], "up")

    def link(self, up: bool) -> None:
        for role, ns in self.ns.items():
            ip("-n", ns, "link", "set", self.dev[role], "up" if up else "down")

    def exec(self, role: str, *cmd: str) -> subprocess.CompletedProcess:
        return subprocess.run(["ip", "netns", "exec", self.ns[role], *cmd],
                              capture_output=True, text=True)  # fmt: skip

    def netem(self, loss_pct: float, delay_ms: float) -> str | None:
        """Loss and delay with ``tc netem`` on both ends; the error if the kernel has none."""
        for role in self.ns:
            r = self.exec(role, "tc", "qdisc", "add", "dev", self.dev[role], "root", "netem",
                          "loss", f"{loss_pct}%", "delay", f"{delay_ms}ms")  # fmt: skip
            if r.returncode != 0:
                return r.stderr.strip() or f"tc exit {r.returncode}"
        return None

    def iptables_loss(self, p: float) -> str | None:
        """Drop each packet leaving either end of the veth with probability ``p``
        (an accounting rule first counts them all); the error if iptables cannot."""
        if shutil.which("iptables") is None:
            return "no iptables (Debian package iptables)"
        for role in self.ns:
            for rule in ([], ["-m", "statistic", "--mode", "random", "--probability", str(p),
                              "-j", "DROP"]):  # fmt: skip
                r = self.exec(role, "iptables", "-A", "OUTPUT", "-o", self.dev[role], *rule)
                if r.returncode != 0:
                    return r.stderr.strip() or f"iptables exit {r.returncode}"
        return None

    def iptables_counts(self) -> dict[str, int]:
        """Packets that left the ends of the veth, and those the loss rule dropped."""
        out = {"packets": 0, "dropped": 0}
        for role in self.ns:
            text = self.exec(role, "iptables", "-L", "OUTPUT", "-v", "-x", "-n").stdout
            for line in text.splitlines():
                f = line.split()
                if len(f) > 2 and f[0].isdigit() and self.dev[role] in f:
                    out["dropped" if "DROP" in f else "packets"] += int(f[0])
        return out

    def relay(self, role: str, log: Path, listen: str, to: str, delay_s: float):
        """A :mod:`delay_relay` in ``role``'s namespace; its counts go to ``log``'s ``.json``."""
        err = open(log, "wb")
        cmd = ["ip", "netns", "exec", self.ns[role], sys.executable, str(RELAY), "--listen",
               listen, "--to", to, "--delay", str(delay_s), "--stats",
               str(log.with_suffix(".json"))]  # fmt: skip
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        err.close()
        self.procs.append(proc)
        return proc

    def start(self, role: str, log: Path, *args: str) -> subprocess.Popen:
        """``skyfuse ARGS`` in ``role``'s namespace (stderr to ``log``)."""
        err = open(log, "wb")
        env = {**os.environ, "XDG_STATE_HOME": str(log.parent / f"state-{log.stem}")}
        cmd = ["ip", "netns", "exec", self.ns[role], sys.executable, "-m",
               "skyfuse.services.cli", *args]  # fmt: skip
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err, env=env, cwd=ROOT)
        err.close()
        self.procs.append(proc)
        return proc

    def stop_all(self) -> None:
        """SIGTERM to every process still running, newest first (then SIGKILL)."""
        for proc in self.procs[::-1]:
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()

    def delete(self) -> None:
        self.stop_all()
        for ns in self.ns.values():  # deleting a namespace deletes its end of the veth
            ip("netns", "del", ns, check=False)


def tag_of(test_name: str) -> str:
    """A short namespace tag from a test's name."""
    return re.sub(r"[^a-z0-9]", "", test_name.split("[")[0][-6:].lower())
