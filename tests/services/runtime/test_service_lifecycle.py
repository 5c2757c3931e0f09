"""Process life cycle: SIGTERM/SIGINT set the stop flag (no KeyboardInterrupt), the stop
and its watchdog work even while the main thread is blocked in a call that never returns
to the interpreter, a third signal exits at once; the single-command entry point; sensor
start alignment."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import time

from service_support import ROOT
from skyfuse.services.sensors.config import SensorServiceConfig, start_time_ns

CHILD = textwrap.dedent(
    """
    import os, sys, time
    from skyfuse.services.runtime.lifecycle import StopFlag
    stop = StopFlag(grace=float(sys.argv[1])).install()
    print("ready", flush=True)
    if sys.argv[2] == "blocked":
        r, w = os.pipe()
        os.read(r, 1)  # never returns: signal handlers cannot end it (PEP 475 retries)
    else:
        while not stop.wait(0.05):
            pass
        print("stopped", stop.signal, flush=True)
        time.sleep(float(sys.argv[3]))
    """
)


def child(*args: str) -> subprocess.Popen:
    p = subprocess.Popen(
        [sys.executable, "-c", CHILD, *args], cwd=ROOT, stdout=subprocess.PIPE, text=True
    )
    assert p.stdout.readline().strip() == "ready"
    return p


def test_sigterm_sets_the_flag_and_the_service_exits_normally():
    p = child("4.5", "loop", "0")
    p.send_signal(signal.SIGINT)  # no KeyboardInterrupt: the loop sees the flag
    out, _ = p.communicate(timeout=10)
    assert p.returncode == 0 and out.strip() == f"stopped {int(signal.SIGINT)}"


def test_stop_and_watchdog_work_while_blocked_in_a_native_call():
    p = child("1.0", "blocked")
    t0 = time.monotonic()
    p.send_signal(signal.SIGTERM)
    p.wait(timeout=10)
    assert p.returncode == 3  # forced exit by the watchdog, not a hang
    assert 0.9 < time.monotonic() - t0 < 4.0


def test_third_signal_exits_at_once():
    p = child("30", "loop", "30")  # a shutdown that would take 30 s
    for _ in range(3):
        p.send_signal(signal.SIGTERM)
        time.sleep(0.2)
    p.wait(timeout=5)
    assert p.returncode == 3


def test_single_command_entry_point_usage_errors():
    r = subprocess.run(
        [sys.executable, "-m", "skyfuse.services.cli", "nosuchcommand"],
        cwd=ROOT, capture_output=True, text=True, timeout=30,
    )  # fmt: skip
    assert r.returncode == 2 and "invalid choice: 'nosuchcommand'" in r.stderr
    r = subprocess.run(
        [sys.executable, "-m", "skyfuse.services.cli", "record", "--out", "x.mcap",
         "--connect", "localhost:7447"],
        cwd=ROOT, capture_output=True, text=True, timeout=30,
    )  # fmt: skip
    assert r.returncode == 2 and "endpoint 'localhost:7447' is not valid" in r.stderr


def test_sensor_start_alignment():
    cfg = SensorServiceConfig(radar="R1", align=10.0)
    now = 1_767_225_603_500_000_000  # xx:xx:03.5
    assert start_time_ns(cfg, now) == 1_767_225_610_000_000_000
    now = 1_767_225_609_200_000_000  # less than 1 s before the boundary: the next one
    assert start_time_ns(cfg, now) == 1_767_225_620_000_000_000
    assert start_time_ns(SensorServiceConfig(radar="R1", start_at=12.5), now) == 12_500_000_000
    assert start_time_ns(SensorServiceConfig(radar="R1"), now) == now
