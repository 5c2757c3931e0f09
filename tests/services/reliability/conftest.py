"""Helpers of the reliability/security service tests: loopback sessions, waiting, and the
listening sockets of a process (read from /proc, Linux)."""

from __future__ import annotations

import os
import signal
import socket
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from service_support import wait_for


def _socket_inodes(pid: int | str) -> set[int]:
    out = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            out.add(int(target[8:-1]))
    return out


def _addr(hex_addr: str, v6: bool) -> str:
    raw = bytes.fromhex(hex_addr)
    if v6:
        raw = b"".join(struct.pack("<I", w) for w in struct.unpack(">4I", raw))
        return socket.inet_ntop(socket.AF_INET6, raw)
    return socket.inet_ntop(socket.AF_INET, struct.pack("<I", int(hex_addr, 16)))


def listening_addresses(pid: int | str = "self") -> list[tuple[str, int]]:
    """``(address, port)`` of every TCP socket in LISTEN state owned by process ``pid``."""
    inodes = _socket_inodes(pid)
    out = []
    for name, v6 in (("tcp", False), ("tcp6", True)):
        path = Path(f"/proc/{pid}/net/{name}")
        if not path.exists():
            continue
        for line in path.read_text().splitlines()[1:]:
            f = line.split()
            if f[3] == "0A" and int(f[9]) in inodes:  # 0A = TCP_LISTEN
                host, port = f[1].split(":")
                out.append((_addr(host, v6), int(port, 16)))
    return out


def stop_process(proc: subprocess.Popen, sig: int = signal.SIGTERM, timeout: float = 8.0):
    """Send ``sig`` and wait; the exit code (``None`` if it had to be killed)."""
    if proc.poll() is None:
        proc.send_signal(sig)
    try:
        return proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        return None


@pytest.fixture
def listening():
    """``listening(pid="self")``: the TCP listening addresses of a process."""
    return listening_addresses


@pytest.fixture
def until():
    """``until(pred, timeout)``: poll until ``pred()`` is true; its final value."""
    return wait_for


@pytest.fixture
def start_skyfuse(tmp_path):
    """``start_skyfuse(*args, log="name")``: a ``skyfuse`` command as a process (stderr to
    ``tmp_path/name.log``), stopped with SIGTERM (then SIGKILL) at teardown."""
    procs: list[subprocess.Popen] = []

    def start(*args: str, log: str = "proc") -> subprocess.Popen:
        err = open(tmp_path / f"{log}.log", "wb")
        proc = subprocess.Popen(
            [sys.executable, "-m", "skyfuse.services.cli", *args],
            stdout=subprocess.DEVNULL,
            stderr=err,
            env=dict(os.environ),
        )
        err.close()
        procs.append(proc)
        return proc

    yield start
    for proc in procs:
        stop_process(proc)
