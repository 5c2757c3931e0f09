"""PlotBatch (+ RadarSite) → CAT048 target reports and CAT034 service messages.

:class:`AsterixPlotWriter` turns the sector batches of one or more radars into data
blocks that :func:`.reader.read_asterix` / :class:`.reader.AsterixStreamDecoder` read
back into the same sectors and plots (to ASTERIX resolution):

* before a radar's first batch, a CAT034 sector crossing at the batch's
  ``sector_start``/``time_start`` opens the sector;
* the plots go out as CAT048 records (one data block per batch, split so that no block
  exceeds ``max_block_bytes``, default 1400 bytes so each fits one UDP datagram),
  in time order;
* the batch is closed by a CAT034 sector crossing at ``sector_start + sector_width``
  and ``time_end``, or by a North marker when that azimuth is north (with I041 scan
  period and, when the site is known, I120 position).

Resolution (LSB): time 1/128 s, range 1/256 NM (7.23 m), azimuth 360/2^16 deg
(96 µrad), altitude 1/4 FL (7.62 m), amplitude 1 dBm, sector azimuth 360/2^8 deg
(CAT034 I020: sector boundaries should be multiples of 1.40625°, e.g. 16 or 32
sectors per turn). Plots have I020 TYP 5 (Mode S roll-call) with a Mode-S address, 2
(SSR) with a Mode-3/A code or an altitude, else 1 (PSR); SIM = 1 when ``simulated``.

Secondary-surveillance columns: ``mode_3a`` with its flags → I070 (V, G, L),
``flight_level`` with its flags → I090 (the ``altitude`` column is written as I090 only
for plots without a ``flight_level``), ``spi`` → I020 SPI, ``mode_s`` → I220,
``callsign`` → I240, ``flight_status`` → I230 STAT, the downlinked parameters → I250 as
the registers BDS 4,0, 5,0 and 6,0 that carry them (:func:`.bds.encode_register`; a
register is written when one of its parameters is known).

Not carried: ``elevation`` (CAT048 has no elevation item), ``doppler``, ``target_id``
(simulation truth): they are dropped and counted in ``stats``. Cartesian batches
(x/y) cannot be written (``ValueError``). Plots outside I040 (range > 256 NM) are
skipped and counted.
"""

from __future__ import annotations

import math
from collections import Counter

from skyfuse.schemas import PlotBatch, RadarSite
from skyfuse.schemas.identity import DOWNLINK_REGISTERS

from . import bds, cat034, cat048
from .reader import NM, SECONDARY_COLUMNS, altitude_to_flight_level
from .sites import sac_sic_of

TWO_PI = 2.0 * math.pi
NS = 1_000_000_000


TICKS_PER_S = 128  # I048/140, I034/030 LSB = 1/128 s
TICKS_PER_DAY = 86_400 * TICKS_PER_S


def time_ticks(t_ns: int) -> int:
    """Absolute time in 1/128 s ticks (rounded)."""
    return (int(t_ns) * TICKS_PER_S + NS // 2) // NS


def tod_of_ticks(ticks: int) -> float:
    return (ticks % TICKS_PER_DAY) / TICKS_PER_S


def datablock(category: int, records: list[bytes]) -> bytes:
    """One data block (CAT, LEN, records) from encoded records."""
    body = b"".join(records)
    if len(body) + 3 > 0xFFFF:
        raise ValueError(f"{len(records)} records ({len(body)} bytes) exceed one data block")
    return bytes([category]) + (len(body) + 3).to_bytes(2, "big") + body


def datablocks(category: int, records: list[bytes], max_bytes: int) -> list[bytes]:
    """Records packed into as few blocks as possible, each at most ``max_bytes`` (a
    record longer than that gets a block of its own)."""
    out: list[bytes] = []
    chunk: list[bytes] = []
    size = 3
    for b in records:
        if chunk and size + len(b) > max_bytes:
            out.append(bytes([category]) + size.to_bytes(2, "big") + b"".join(chunk))
            chunk, size = [], 3
        chunk.append(b)
        size += len(b)
    if chunk:
        out.append(bytes([category]) + size.to_bytes(2, "big") + b"".join(chunk))
    return out


class AsterixPlotWriter:
    """Stateful encoder of PlotBatches to ASTERIX data blocks (see module docstring).

    ``sites``: radar id → RadarSite, for I041 (scan period) and I120 (position) in
    North markers. Radar ids of the form ``"SAC-SIC"`` (:func:`.sites.radar_id_for`)
    give their own SAC/SIC; others (e.g. a simulator's ``"radar"``) need an entry in
    ``sac_sic`` (radar id → (SAC, SIC)); read back, they are named ``"SAC-SIC"``.
    ``simulated``: set I048/020 SIM (the plots come from a simulator)."""

    def __init__(
        self,
        sites: dict[str, RadarSite] | None = None,
        *,
        sac_sic: dict[str, tuple[int, int]] | None = None,
        simulated: bool = True,
        max_block_bytes: int = 1400,
    ) -> None:
        if max_block_bytes < 64 or max_block_bytes > 65535:
            raise ValueError(f"max_block_bytes = {max_block_bytes}: must be in 64..65535")
        self.sac_sic = dict(sac_sic or {})
        for rid, (sac, sic) in self.sac_sic.items():
            if not (0 <= sac <= 255 and 0 <= sic <= 255):
                raise ValueError(f"sac_sic[{rid!r}] = ({sac}, {sic}): SAC and SIC are 0..255")
        self.sites = dict(sites or {})
        self.simulated = simulated
        self.max_block_bytes = max_block_bytes
        self.stats: Counter = Counter()
        self._last_end: dict[str, tuple[int, float]] = {}

    def encode_batch(self, batch: PlotBatch) -> list[bytes]:
        """Data blocks (each a ready UDP payload) for one batch, in send order."""
        if batch.is_cartesian:
            raise ValueError(
                f"batch {batch.radar_id}#{batch.seq} has x/y plots: CAT048 carries polar "
                "plots (range/azimuth) only"
            )
        if batch.radar_id in self.sac_sic:
            sac, sic = self.sac_sic[batch.radar_id]
        else:
            try:
                sac, sic = sac_sic_of(batch.radar_id)
            except ValueError as exc:
                raise ValueError(f"{exc}; or map it with sac_sic={{id: (SAC, SIC)}}") from None
        out: list[bytes] = []
        last = self._last_end.get(batch.radar_id)
        start_az = batch.sector_start
        if last is None or last[0] != batch.time_start or not _same_az(last[1], start_az):
            out.append(self._service(sac, sic, batch.radar_id, start_az, batch.time_start))
        records = self._plot_records(batch, sac, sic)
        out.extend(datablocks(cat048.CATEGORY, records, self.max_block_bytes))
        end_az = (batch.sector_start + batch.sector_width) % TWO_PI
        out.append(self._service(sac, sic, batch.radar_id, end_az, batch.time_end))
        self._last_end[batch.radar_id] = (batch.time_end, end_az)
        self.stats["batches"] += 1
        return out

    def encode(self, batches: list[PlotBatch]) -> bytes:
        """Concatenated data blocks of several batches (a raw ``.ast`` file's bytes)."""
        return b"".join(b for batch in batches for b in self.encode_batch(batch))

    # ----------------------------------------------------------------------------
    def _service(self, sac: int, sic: int, radar_id: str, az: float, t_ns: int) -> bytes:
        site = self.sites.get(radar_id)
        if _same_az(az, 0.0):
            rec = cat034.encode_record(
                sac=sac,
                sic=sic,
                message_type=cat034.NORTH_MARKER,
                tod=tod_of_ticks(time_ticks(t_ns)),
                period_s=site.scan_period if site is not None else None,
                position=(site.lat, site.lon, site.alt) if site is not None else None,
            )
            self.stats["north_markers"] += 1
        else:
            rec = cat034.encode_record(
                sac=sac,
                sic=sic,
                message_type=cat034.SECTOR_CROSSING,
                tod=tod_of_ticks(time_ticks(t_ns)),
                sector_deg=math.degrees(az),
            )
            q = round(math.degrees(az) * 256.0 / 360.0) * 360.0 / 256.0
            if abs(q - math.degrees(az)) > 1e-6:
                self.stats["sector_azimuth_quantised"] += 1
            self.stats["sector_crossings"] += 1
        return datablock(cat034.CATEGORY, [rec])

    def _plot_records(self, batch: PlotBatch, sac: int, sic: int) -> list[bytes]:
        n = len(batch)
        for name in ("elevation", "doppler", "target_id"):
            if getattr(batch, name) is not None:
                self.stats[f"dropped_{name}_column"] += 1
        alt = batch.altitude or [None] * n
        amp = batch.amplitude or [None] * n
        ms = batch.mode_s or [None] * n
        m3a = batch.mode_3a or [None] * n
        present = [c for c in SECONDARY_COLUMNS if getattr(batch, c) is not None]
        secondary = [getattr(batch, c) for c in present]
        records = []
        assert batch.range is not None and batch.azimuth is not None
        # Plot times are kept inside (start, end] of the sector in ticks, so that the
        # reader (which assigns plots to sectors by time) finds them in this batch.
        lo, hi = time_ticks(batch.time_start) + 1, time_ticks(batch.time_end)
        for i in range(n):
            rho_nm = batch.range[i] / NM
            if rho_nm * 256.0 > 0xFFFF + 0.5:
                self.stats["plot_beyond_256_nm"] += 1
                continue
            extra = {c: col[i] for c, col in zip(present, secondary) if col[i] is not None}
            fl = extra.pop("flight_level", None)
            if fl is None and alt[i] is not None:
                fl = altitude_to_flight_level(alt[i])
            if fl is not None and not -2048.0 <= fl < 2047.75:
                self.stats["altitude_out_of_range"] += 1
                fl = None
            if ms[i] is not None:
                typ = 5
            elif m3a[i] is not None or fl is not None:
                typ = 2
            else:
                typ = 1
            records.append(
                cat048.encode_record(
                    sac=sac,
                    sic=sic,
                    tod=tod_of_ticks(min(max(time_ticks(batch.time[i]), lo), max(hi, lo))),
                    rho_nm=rho_nm,
                    theta_deg=math.degrees(batch.azimuth[i]),
                    typ=typ,
                    sim=self.simulated,
                    flight_level=fl,
                    mode_3a=m3a[i],
                    mode_s=ms[i],
                    amplitude_dbm=amp[i] if amp[i] is None or math.isfinite(amp[i]) else None,
                    **_mode_s_values(extra),
                )
            )
            self.stats["plots"] += 1
        return records


def _mode_s_values(extra: dict) -> dict:
    """The encode_record keywords of a plot's secondary values: the flags as they are,
    the downlinked parameters as I250 registers."""
    registers = []
    for name, params in DOWNLINK_REGISTERS.items():
        if any(p in extra for p in params):
            registers.append((bds.encode_register(name, extra), int(name[0]) << 4))
            for p in params:
                extra.pop(p, None)
    if registers:
        extra["registers"] = registers
    return extra


def _same_az(a: float, b: float) -> bool:
    return abs((a - b + math.pi) % TWO_PI - math.pi) < 1e-9
