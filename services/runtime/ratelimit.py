"""Rate-limited log lines: hostile or broken input must not flood the log.

:class:`RateLimitedLog` is a token bucket: at most ``burst`` lines at once and ``rate``
lines per second on average, whatever the number of distinct messages; the lines it
suppresses are counted and announced in the next line it lets through."""

from __future__ import annotations

import logging
import time


class RateLimitedLog:
    """Token-bucket limited logging to ``logger`` (``burst`` lines, refilled at ``rate``/s)."""

    def __init__(
        self, logger: logging.Logger, *, rate: float = 1.0, burst: int = 10, clock=time.monotonic
    ) -> None:
        self.logger = logger
        self.rate = rate
        self.burst = burst
        self._clock = clock
        self._tokens = float(burst)
        self._last = clock()
        self.suppressed = 0
        """Lines suppressed since the last one written."""
        self.suppressed_total = 0

    def log(self, level: int, msg: str, *args) -> bool:
        """Write ``msg % args`` if the bucket allows; ``False`` if suppressed."""
        now = self._clock()
        self._tokens = min(self.burst, self._tokens + (now - self._last) * self.rate)
        self._last = now
        if self._tokens < 1.0:
            self.suppressed += 1
            self.suppressed_total += 1
            return False
        self._tokens -= 1.0
        if self.suppressed:
            msg = f"{msg} [{self.suppressed} similar lines suppressed]"
            self.suppressed = 0
        self.logger.log(level, msg, *args)
        return True

    def warning(self, msg: str, *args) -> bool:
        return self.log(logging.WARNING, msg, *args)
