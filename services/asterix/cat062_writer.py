"""Fused tracks (:class:`schemas.Track` / :class:`schemas.TrackBatch`) → CAT062.

Items written per track (edition 1.20 layout, in UAP order):

==========  ===================================================================
I062/010    SAC/SIC of this tracker (constructor arguments)
I062/015    service identification (``service_id``)
I062/070    time of track information: ``track.time`` → time of day, LSB 1/128 s
I062/105    WGS-84 ``lat``/``lon``, LSB 180/2^25 deg
I062/100    system Cartesian x/y (LSB 0.5 m), only for a stereographic batch frame
            (the system plane of I100 is a stereographic projection)
I062/185    velocity VX = ``vel_east``, VY = ``vel_north``, LSB 0.25 m/s
I062/040    track number = ``track_id`` mod 65536 (I040 has 16 bits)
I062/060    Mode-3/A code, I062/245 target identification, I062/380 aircraft
            derived data: :mod:`.cat062_identity`
I062/080    status: MON (1 = monosensor: at most one radar updated the track; 0 =
            multisensor: two or more), SPI, CNF (0 confirmed /
            1 tentative), SIM, TSB (first message of the track from this writer),
            TSE (last message: status terminated), EMS (emergency status, in the
            fifth octet, only when the track has an emergency)
I062/290    ages per technology, I062/295 ages of the data: :mod:`.cat062_identity`
I062/136    measured flight level: ``flight_level`` (the last Mode C level the track
            shows), else where the altitude is known ``alt`` / 30.48 m (the inverse
            of the reader's FL → altitude; pressure altitude taken as height, see
            docs/asterix.md), LSB 1/4 FL
I062/500    accuracies from the state covariance: APC σx, σy (m, LSB 0.5), COV
            sign(Cxy)·√|Cxy| (m), APW σlat, σlon (deg, via the WGS-84 radii of
            curvature), ATV σvx, σvy (m/s, LSB 0.25); each clipped to its item's range
I062/340    the last plot's measured information: :mod:`.cat062_identity`
==========  ===================================================================

Position/velocity axes of the covariance: the state labels ``x``, ``y``, ``vx``,
``vy`` of the batch; x east / y north for stereographic and planar frames, x north /
y east for NED (swapped to east/north here).
"""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

import numpy as np
from skyfuse.schemas import FrameKind, Track, TrackBatch, TrackStatus

from . import cat062
from .cat062_identity import build_identity, identity_items, pack_identity
from .layout import RecordLayout, build_fspec
from .reader import altitude_to_flight_level
from .writer import datablocks, time_ticks

WGS84_A = 6_378_137.0
WGS84_E2 = 6.694_379_990_14e-3
LSB_DEG_105 = 180.0 / 2**25
EMS = {"general": 1, "medical": 2, "minimum_fuel": 3, "no_communications": 4,
       "unlawful_interference": 5, "downed_aircraft": 6}  # fmt: skip
"""I062/080 EMS code of each :class:`schemas.Emergency`."""


def metres_per_degree(lat_deg: float) -> tuple[float, float]:
    """(m per degree of latitude, m per degree of longitude) on WGS-84 at ``lat_deg``:
    meridional radius M and prime-vertical radius N·cos φ, times π/180."""
    s = math.sin(math.radians(lat_deg))
    w = math.sqrt(1.0 - WGS84_E2 * s * s)
    m = WGS84_A * (1.0 - WGS84_E2) / w**3
    n = WGS84_A / w
    k = math.pi / 180.0
    return m * k, n * math.cos(math.radians(lat_deg)) * k


def _clip_raw(value: float, lsb: float, lo: int, hi: int) -> int:
    return int(min(max(round(value / lsb), lo), hi))


class Cat062Writer:
    """Stateful CAT062 encoder (remembers which track numbers it has sent, for TSB).

    ``encode_batch(batch)`` → data blocks (≤ ``max_block_bytes`` each, one UDP datagram
    each); ``encode_track(track, frame, state_labels)`` → one libasterix record."""

    def __init__(
        self,
        *,
        sac: int,
        sic: int,
        service_id: int = 1,
        simulated: bool = False,
        max_block_bytes: int = 1400,
    ) -> None:
        for name, v in (("sac", sac), ("sic", sic), ("service_id", service_id)):
            if not 0 <= int(v) <= 255:
                raise ValueError(f"{name} = {v}: must be in 0..255")
        self.sac, self.sic, self.service_id = int(sac), int(sic), int(service_id)
        self.simulated = simulated
        self.max_block_bytes = max_block_bytes
        self.stats: Counter = Counter()
        self._sent: set[int] = set()

    def encode_batch(self, batch: TrackBatch) -> list[bytes]:
        records = [self.encode_track(t, batch.frame.kind, batch.state_labels) for t in batch.tracks]
        return datablocks(cat062.CATEGORY, records, self.max_block_bytes)

    def encode(self, batches: list[TrackBatch]) -> bytes:
        """Concatenated data blocks of several batches (a raw file's bytes)."""
        return b"".join(b for batch in batches for b in self.encode_batch(batch))

    def encode_track(self, track: Track, frame: FrameKind, state_labels: list[str]) -> bytes:
        """One CAT062 record (bytes); updates the first/last-message bookkeeping."""
        first = track.track_id not in self._sent
        self._sent.add(track.track_id)
        last = track.status == TrackStatus.TERMINATED
        if last:
            self._sent.discard(track.track_id)
        raw = self.raw_items(track, frame, state_labels, first=first, last=last)
        self.stats["tracks"] += 1
        return pack_record(raw)

    def raw_items(
        self,
        track: Track,
        frame: FrameKind,
        state_labels: list[str],
        *,
        first: bool,
        last: bool,
    ) -> dict[str, Any]:
        """Raw (LSB-count, masked to the item width) values of the items of one track."""
        number = track.track_id % 65536
        if number != track.track_id:
            self.stats["track_number_wrapped"] += 1
        raw: dict[str, Any] = {
            "010": (self.sac, self.sic),
            "015": self.service_id,
            "070": time_ticks(track.time) % (86_400 * 128),
            "105": (
                _clip_raw(track.lat, LSB_DEG_105, -(2**31), 2**31 - 1) & 0xFFFFFFFF,
                _clip_raw(track.lon, LSB_DEG_105, -(2**31), 2**31 - 1) & 0xFFFFFFFF,
            ),
        }
        idx = {name: i for i, name in enumerate(state_labels)}
        if frame == FrameKind.STEREOGRAPHIC and "x" in idx and "y" in idx:
            x, y = track.state[idx["x"]], track.state[idx["y"]]
            lim = 2**23 - 1
            if abs(x) / 0.5 <= lim and abs(y) / 0.5 <= lim:
                raw["100"] = (
                    _clip_raw(x, 0.5, -lim - 1, lim) & 0xFFFFFF,
                    _clip_raw(y, 0.5, -lim - 1, lim) & 0xFFFFFF,
                )
            else:
                self.stats["i100_out_of_range"] += 1
        raw["185"] = (
            _clip_raw(track.vel_east, 0.25, -32768, 32767) & 0xFFFF,
            _clip_raw(track.vel_north, 0.25, -32768, 32767) & 0xFFFF,
        )
        identity, clipped = identity_items(track)
        if clipped:
            self.stats["identity_value_clipped"] += clipped
        raw.update((k, identity[k]) for k in ("060", "245", "380") if k in identity)
        raw["040"] = number
        raw["080"] = (
            int(len(track.radars) <= 1),  # MON: multisensor only with two radars or more
            int(bool(track.spi)),  # SPI
            int(track.status == TrackStatus.TENTATIVE),  # CNF
            int(self.simulated),  # SIM
            int(last),  # TSE
            int(first),  # TSB
            EMS.get(track.emergency or "", 0),  # EMS
        )
        raw.update((k, identity[k]) for k in ("290", "295") if k in identity)
        fl = track.flight_level
        if fl is None and track.alt is not None:
            fl = altitude_to_flight_level(track.alt)
        if fl is not None:
            raw["136"] = _clip_raw(fl, 0.25, -32768, 32767) & 0xFFFF
        acc = self._accuracies(track, frame, idx)
        if acc:
            raw["500"] = acc
        if "340" in identity:
            raw["340"] = identity["340"]
        return raw

    def _accuracies(self, track: Track, frame: FrameKind, idx: dict[str, int]) -> dict[str, Any]:
        if "x" not in idx or "y" not in idx:
            return {}
        cov = np.asarray(track.covariance, dtype=float)
        ix, iy = idx["x"], idx["y"]
        east, north = (iy, ix) if frame == FrameKind.NED else (ix, iy)
        var_e, var_n, c_en = cov[east, east], cov[north, north], cov[east, north]
        out: dict[str, Any] = {}
        sx, sy = math.sqrt(max(var_e, 0.0)), math.sqrt(max(var_n, 0.0))
        out["APC"] = (_clip_raw(sx, 0.5, 0, 0xFFFF), _clip_raw(sy, 0.5, 0, 0xFFFF))
        root = math.copysign(math.sqrt(abs(c_en)), c_en)
        out["COV"] = _clip_raw(root, 0.5, -32768, 32767) & 0xFFFF
        m_lat, m_lon = metres_per_degree(track.lat)
        out["APW"] = (
            _clip_raw(sy / m_lat, LSB_DEG_105, 0, 0xFFFF),
            _clip_raw(sx / max(m_lon, 1e-9), LSB_DEG_105, 0, 0xFFFF),
        )
        if "vx" in idx and "vy" in idx:
            ive, ivn = (idx["vy"], idx["vx"]) if frame == FrameKind.NED else (idx["vx"], idx["vy"])
            svx = math.sqrt(max(cov[ive, ive], 0.0))
            svy = math.sqrt(max(cov[ivn, ivn], 0.0))
            out["ATV"] = (_clip_raw(svx, 0.25, 0, 0xFF), _clip_raw(svy, 0.25, 0, 0xFF))
        return out


def _pack_080(mon: int, spi: int, cnf: int, sim: int, tse: int, tsb: int, ems: int) -> bytes:
    """I080: two octets, or five (FX through octets 3 and 4) to carry EMS."""
    out = bytearray((mon << 7 | spi << 6 | cnf << 1 | 1, sim << 7 | tse << 6 | tsb << 5))
    if ems:
        out[1] |= 1
        out += bytes((1, 1, ems << 3))
    return bytes(out)


def _pack_500(acc: dict[str, Any]) -> bytes:
    subs = [k for k in ("APC", "COV", "APW", "ATV") if k in acc]
    body = bytearray(build_fspec(_I500_LAYOUT, subs))
    if "APC" in acc:
        body += acc["APC"][0].to_bytes(2, "big") + acc["APC"][1].to_bytes(2, "big")
    if "COV" in acc:
        body += acc["COV"].to_bytes(2, "big")
    if "APW" in acc:
        body += acc["APW"][0].to_bytes(2, "big") + acc["APW"][1].to_bytes(2, "big")
    if "ATV" in acc:
        body += bytes(acc["ATV"])
    return bytes(body)


_PACK = {
    "010": bytes,
    "015": lambda v: bytes((v,)),
    "070": lambda v: v.to_bytes(3, "big"),
    "105": lambda v: v[0].to_bytes(4, "big") + v[1].to_bytes(4, "big"),
    "100": lambda v: v[0].to_bytes(3, "big") + v[1].to_bytes(3, "big"),
    "185": lambda v: v[0].to_bytes(2, "big") + v[1].to_bytes(2, "big"),
    "040": lambda v: v.to_bytes(2, "big"),
    "080": lambda v: _pack_080(*v),
    "136": lambda v: v.to_bytes(2, "big"),
    "500": _pack_500,
}
_UAP_INDEX = {name: i for i, (name, _) in enumerate(cat062.LAYOUT.slots) if name}


def pack_record(raw: dict[str, Any]) -> bytes:
    """Bytes of a CAT062 record from :meth:`Cat062Writer.raw_items` values, packed
    directly in UAP order (identical to :func:`build_record`'s libasterix encoding,
    differential test; ~20× faster)."""
    names = sorted(raw, key=_UAP_INDEX.__getitem__)
    body = b"".join(_PACK[n](raw[n]) if n in _PACK else pack_identity(n, raw[n]) for n in names)
    return build_fspec(cat062.LAYOUT, names) + body


def build_record(raw: dict[str, Any]) -> Any:
    """The same record built with libasterix (the reference encoder)."""
    mon, spi, cnf, sim, tse, tsb, ems = raw["080"]
    i080 = [(mon, spi, 0, 0, cnf, None), (sim, tse, tsb, 0, 0, 0, 0, None)]
    if ems:
        i080 += [(0, 0, 0, 0, 0, None), (0, 0, 0, 0, 0, 0, 0, None), (0, ems, 0, 0, None)]
    items: dict[str, Any] = {
        "010": (("SAC", raw["010"][0]), ("SIC", raw["010"][1])),
        "015": raw["015"],
        "070": raw["070"],
        "105": (("LAT", raw["105"][0]), ("LON", raw["105"][1])),
        "185": (("VX", raw["185"][0]), ("VY", raw["185"][1])),
        "040": raw["040"],
        "080": tuple(i080),
    }
    if "100" in raw:
        items["100"] = (("X", raw["100"][0]), ("Y", raw["100"][1]))
    if "136" in raw:
        items["136"] = raw["136"]
    if "500" in raw:
        acc = raw["500"]
        i500: dict[str, Any] = {}
        if "APC" in acc:
            i500["APC"] = (("X", acc["APC"][0]), ("Y", acc["APC"][1]))
        if "COV" in acc:
            i500["COV"] = acc["COV"]
        if "APW" in acc:
            i500["APW"] = (("LAT", acc["APW"][0]), ("LON", acc["APW"][1]))
        if "ATV" in acc:
            i500["ATV"] = (("X", acc["ATV"][0]), ("Y", acc["ATV"][1]))
        items["500"] = i500
    for name in ("060", "245", "380", "290", "295", "340"):
        if name in raw:
            items[name] = build_identity(name, raw[name])
    return cat062.SPEC.cv_record.create(items)


_I500_LAYOUT = RecordLayout(
    2, tuple((name, None) for name in ("APC", "COV", "APW", "AGA", "ABA", "ATV", "AA", "ARC"))
)
