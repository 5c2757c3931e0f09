"""Configuration of a sensor process (``skyfuse sensor``) and what all its sources share:
the start instant (``--start-at``/``--align``), ``HOST:PORT`` parsing and the counters.

Sources, one module each: :mod:`.simulated` (a scenario's radar), :mod:`.asterix_file`
(an ASTERIX recording), :mod:`.asterix_udp` (a live ASTERIX UDP feed), :mod:`.replay`
(an MCAP recording); :mod:`.fleet` publishes the radars of an ASTERIX input.
"""

from __future__ import annotations

import datetime as dt
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from pydantic import Field, field_validator
from skyfuse.schemas import keys
from skyfuse.services.asterix.read_options import AsterixReadOptions
from skyfuse.services.runtime.transport import PLOT_CACHE
from skyfuse.services.sensors.scenario_config import ScenarioSelection


class SensorServiceConfig(ScenarioSelection, AsterixReadOptions):
    """Options of ``skyfuse sensor`` (TOML table ``[sensor]``): the input (a scenario's
    simulated radar, ``--replay`` MCAP, ``--asterix`` file or ``--asterix-udp`` feed), its
    pacing and start, and the Status period."""

    radar: str | None = Field(
        None,
        description="Radar id in the scenario (e.g. R1); with --asterix/--asterix-udp: only "
        "this radar (SAC-SIC, e.g. 25-201)",
    )
    speed: float = Field(1.0, gt=0, le=1000, description="Time scale: 10 = ten times faster")
    replay: Path | None = Field(None, description="Publish this radar's batches from an MCAP")
    asterix: Path | None = Field(
        None,
        description="Publish every sensor of this ASTERIX recording (.pcap or raw .ast: CAT048/"
        "CAT034 radars, CAT010/CAT020/CAT021 surface radar, multilateration, ADS-B), paced by "
        "the plot times",
    )
    asterix_udp: str | None = Field(
        None,
        description="Receive a live ASTERIX UDP stream (CAT048/CAT034, CAT010/CAT020/CAT021) on "
        "HOST:PORT (e.g. 127.0.0.1:30048) and publish each sector or report cycle as it "
        "completes",
    )
    sites: Path | None = Field(
        None, description="ASTERIX sites TOML ([[radar]] sac, sic, lat, lon, alt, ...)"
    )
    date: dt.date | None = Field(
        None,
        description="ASTERIX: UTC date of the first record, YYYY-MM-DD (default: --asterix: the "
        "pcap capture time, else today; --asterix-udp: the receive clock, each record on the "
        "day nearest its arrival — give --date for an old capture)",
    )
    data_start: float | None = Field(
        None,
        gt=0,
        description="--asterix: the recording time (Unix s, UTC) that the start instant maps to "
        "(default: the end of the file's first batch); sensor processes of recordings of one "
        "period given the same --data-start and --start-at publish in step",
    )
    max_plot_delay: float | None = Field(
        None,
        ge=0,
        le=60,
        description="ASTERIX: s a closed sector waits for late plots (default: 30 for a file, "
        "0 for --asterix-udp)",
    )
    truth: bool = Field(False, description="Also publish the simulation truth")
    wait_for: list[str] = Field(
        default_factory=list,
        description="Service names (e.g. fusion,recorder) to wait for before starting",
    )
    wait_timeout: float = Field(15.0, gt=0, description="How long to wait for them, s")
    start_at: float | None = Field(
        None,
        gt=0,
        description="Unix time (s) the scenario start (--replay: the recording's start) maps "
        "to; sensors given the same value run in step (default: now)",
    )
    align: float | None = Field(
        None,
        gt=0,
        le=3600,
        description="Start at the next wall-clock multiple of this many s (>= 1 s ahead), "
        "after --wait-for: sensors started apart then run in step",
    )
    status_interval: float = Field(2.0, gt=0, description="Status publication period, s")
    cache_batches: int = Field(
        PLOT_CACHE,
        ge=1,
        le=1_000_000,
        description="Plot batches each radar's publisher keeps for receivers that missed "
        "them (a stalled or cut-off fusion service or recorder gets them back); what is "
        "older is counted as lost by the receivers",
    )
    linger: float = Field(
        0.5, ge=0, le=30, description="Seconds to stay connected after the last batch"
    )
    state_dir: Path | None = Field(
        None,
        description="Directory of the sensor's progress (simulated radar: where it "
        "stopped; --asterix-udp: the sequence-number ceilings), to continue after a "
        "restart (default: $XDG_STATE_HOME/skyfuse/sensor-{radar or asterix-udp})",
    )
    resume_max_age: float | None = Field(
        60.0,
        ge=0,
        description="Simulated radar: continue after the last published batch if the "
        "previous run stopped at most this long ago, s ('off': always from the start)",
    )

    @field_validator("resume_max_age", mode="before")
    @classmethod
    def _off(cls, v):
        return None if isinstance(v, str) and v.strip().lower() in ("off", "none") else v

    @field_validator("radar")
    @classmethod
    def _id(cls, v: str | None) -> str | None:
        return None if v is None else keys.check_id(v, "radar id")

    @field_validator("asterix_udp")
    @classmethod
    def _udp(cls, v: str | None) -> str | None:
        if v is not None:
            parse_host_port(v, "asterix_udp")
        return v

    @property
    def mode(self) -> str:
        """``simulate``, ``replay``, ``asterix`` or ``asterix-udp``."""
        if self.asterix is not None:
            return "asterix"
        if self.asterix_udp is not None:
            return "asterix-udp"
        return "replay" if self.replay is not None else "simulate"


def parse_host_port(text: str, what: str = "address") -> tuple[str, int]:
    """``HOST:PORT`` → (host, port); ``ValueError`` naming ``what`` if malformed."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) <= 65535:
        raise ValueError(f"{what} {text!r} is not HOST:PORT with a port in 1..65535")
    return host.strip("[]"), int(port)


def start_time_ns(cfg: SensorServiceConfig, now_ns: int | None = None) -> int:
    """The wall-clock instant (ns) the scenario start maps to: ``start_at``, else the next
    multiple of ``align`` seconds at least 1 s ahead, else now."""
    now_ns = time.time_ns() if now_ns is None else now_ns
    if cfg.start_at is not None:
        return round(cfg.start_at * 1e9)
    if cfg.align is not None:
        step = round(cfg.align * 1e9)
        return -(-(now_ns + 1_000_000_000) // step) * step
    return now_ns


@dataclass
class SensorStats:
    published: Counter = field(default_factory=Counter)
    plots: int = 0
    late_s: float = 0.0
    """Worst lateness of a publication behind its due wall-clock time, s."""
    interrupted: bool = False

    def wait_until(self, due_ns: int, stop) -> bool:
        """Sleep until the wall-clock instant ``due_ns`` (or until ``stop`` is set); record
        the lateness when already past it. ``False`` (and ``interrupted``) if stopped."""
        delay = (due_ns - time.time_ns()) / 1e9
        if (delay > 0 and stop.wait(delay)) or stop.is_set():
            self.interrupted = True
            return False
        self.late_s = max(self.late_s, -delay)
        return True
