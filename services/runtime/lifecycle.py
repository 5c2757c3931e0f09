"""Process life cycle of the long-running services: signals, bounded shutdown, exit codes.

* SIGINT and SIGTERM only **set an Event** (:class:`StopFlag`); the service loop sees it
  within its poll interval, leaves its ``with open_session(...)`` block (which closes the
  Zenoh session) and returns. Handlers never raise ``KeyboardInterrupt``, so a second
  Ctrl-C cannot land inside ``Session.__exit__`` (stack-notes).
* A watchdog thread bounds the shutdown: if the process is still alive ``grace`` seconds
  after the first signal, it exits with :data:`EXIT_SHUTDOWN_TIMEOUT`. A third signal
  exits at once.

Exit codes (shared by every ``skyfuse`` command):

====  ===========================================================================
0     finished, or stopped cleanly on request (SIGINT/SIGTERM) for the services
1     the job failed (e.g. a Zenoh session could not be opened, a child failed)
2     bad usage or configuration
3     the shutdown did not finish within the grace period (forced exit)
130   an interactive batch command (replay, demo) was interrupted before the end
====  ===========================================================================
"""

from __future__ import annotations

import faulthandler
import logging
import os
import signal
import socket
import sys
import threading
import time
from types import FrameType

log = logging.getLogger(__name__)

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_SHUTDOWN_TIMEOUT, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
DEFAULT_GRACE_S = 4.5


class StopFlag:
    """Set by SIGINT/SIGTERM (or :meth:`set`); services poll :meth:`is_set` / :meth:`wait`."""

    def __init__(self, grace: float = DEFAULT_GRACE_S) -> None:
        self._event = threading.Event()
        self.grace = grace
        self.signal: int | None = None
        self._count = 0
        self._previous: dict[int, object] = {}

    def is_set(self) -> bool:
        return self._event.is_set()

    def wait(self, timeout: float | None = None) -> bool:
        return self._event.wait(timeout)

    def set(self, signum: int | None = None) -> None:
        first = not self._event.is_set()
        if signum is not None and self.signal is None:
            self.signal = signum
        self._event.set()
        if first and self.grace > 0:
            threading.Thread(target=self._watchdog, name="shutdown-watchdog", daemon=True).start()

    def _watchdog(self) -> None:
        time.sleep(self.grace)
        log.error("shutdown did not finish within %.1f s: forcing exit", self.grace)
        _hard_exit(EXIT_SHUTDOWN_TIMEOUT)

    def _on_signal(self, signum: int) -> None:
        self._count += 1
        name = signal.Signals(signum).name
        if self._count == 1:
            log.info("%s received: stopping", name)
        elif self._count == 2:
            log.warning("%s received again: still stopping (once more to force exit)", name)
        else:
            _hard_exit(EXIT_SHUTDOWN_TIMEOUT)
        self.set(signum)

    @staticmethod
    def _python_handler(signum: int, frame: FrameType | None) -> None:
        """Python-level handler: only there so SIGINT raises no KeyboardInterrupt; the
        work is done by the wakeup thread."""

    def _wakeup_loop(self, sock: socket.socket) -> None:
        while True:
            try:
                data = sock.recv(64)
            except OSError:
                return
            if not data:
                return
            for signum in data:
                if signum in (signal.SIGINT, signal.SIGTERM):
                    self._on_signal(signum)

    def install(self) -> StopFlag:
        """Install the SIGINT/SIGTERM handling (main thread only); returns ``self``.

        The C-level signal handler writes the signal number to a socket (``set_wakeup_fd``)
        that a thread reads: the stop request (and the shutdown watchdog) therefore work
        even while the main thread is blocked inside a native call, where Python-level
        handlers cannot run."""
        if threading.current_thread() is not threading.main_thread():
            return self
        # `kill -USR1 PID` prints every thread's stack to stderr, even if one holds the GIL
        faulthandler.register(signal.SIGUSR1, all_threads=True)
        r, w = socket.socketpair()
        w.setblocking(False)
        self._sockets = (r, w)
        self._previous_fd = signal.set_wakeup_fd(w.fileno(), warn_on_full_buffer=False)
        threading.Thread(
            target=self._wakeup_loop, args=(r,), name="signal-wakeup", daemon=True
        ).start()
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._previous[sig] = signal.signal(sig, self._python_handler)
        return self

    def restore(self) -> None:
        for sig, h in self._previous.items():
            signal.signal(sig, h)
        if self._previous:
            signal.set_wakeup_fd(self._previous_fd)
            for sock in self._sockets:
                sock.close()
        self._previous.clear()

    def __enter__(self) -> StopFlag:
        return self.install()

    def __exit__(self, *exc: object) -> None:
        self.restore()


def _hard_exit(code: int) -> None:
    try:
        sys.stderr.flush()
        sys.stdout.flush()
    finally:
        os._exit(code)


class RateWindow:
    """Events per second over a sliding window of ``window_s`` seconds (monotonic clock)."""

    def __init__(self, window_s: float = 5.0) -> None:
        self.window_s = window_s
        self._items: list[tuple[float, int]] = []

    def add(self, n: int, now: float | None = None) -> None:
        now = time.monotonic() if now is None else now
        self._items.append((now, n))
        self._trim(now)

    def _trim(self, now: float) -> None:
        cut = now - self.window_s
        i = 0
        while i < len(self._items) and self._items[i][0] < cut:
            i += 1
        if i:
            del self._items[:i]

    def rate(self, now: float | None = None) -> float:
        now = time.monotonic() if now is None else now
        self._trim(now)
        return sum(n for _, n in self._items) / self.window_s
