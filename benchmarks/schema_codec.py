"""Encode/decode rate of a 500-plot PlotBatch (JSON via pydantic), the wire format.

python benchmarks/schema_codec.py [--plots 500] [--seconds 2] [--secondary] [--json out.json]

``--secondary`` adds the secondary-surveillance columns a Mode S radar's plots carry
(schemas.identity: codes and flags, callsign, flight level, the downlinked parameters of
about half the plots), as the ASTERIX reader fills them, and times what the fusion does
with them on top of decoding: the tracker's view of a decoded batch's identity
(``fusion.tracker.identity.plot_identity`` of a freshly decoded batch: the columns as
arrays, the callsigns packed; ``identity_batches_per_s``).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time

import numpy as np
from skyfuse.schemas import PlotBatch


def make_batch(n: int, seed: int = 0, secondary: bool = False) -> PlotBatch:
    rng = np.random.default_rng(seed)
    t0 = 1_767_225_600_000_000_000
    return PlotBatch(
        radar_id="bench",
        scan=10,
        seq=160,
        sector_start=0.0,
        sector_width=2 * math.pi / 16,
        time_start=t0,
        time_end=t0 + 250_000_000,
        time=np.sort(rng.integers(t0, t0 + 250_000_000, n)).tolist(),
        range=rng.uniform(1e3, 2.5e5, n).tolist(),
        azimuth=rng.uniform(0, 2 * math.pi / 16, n).tolist(),
        altitude=rng.uniform(0, 1.2e4, n).tolist(),
        amplitude=rng.uniform(0, 60, n).tolist(),
        mode_s=[int(v) if v > 0.3 else None for v in rng.uniform(0, 1, n)],
        target_id=rng.integers(-1, 100, n).tolist(),
        **(secondary_columns(n) if secondary else {}),
    )


def secondary_columns(n: int, seed: int = 1) -> dict:
    """Secondary-surveillance columns of ``n`` plots: 80 % with a reply, half of those
    with downlinked parameters."""
    from skyfuse.schemas.identity import DOWNLINKED

    rng = np.random.default_rng(seed)
    reply = rng.random(n) < 0.8
    ehs = reply & (rng.random(n) < 0.5)

    def where(mask, values):
        return [v if m else None for m, v in zip(mask.tolist(), values)]

    cols = {
        "mode_3a": where(reply, rng.integers(0, 4096, n).tolist()),
        "callsign": where(reply, [f"ABC{i % 9000}" for i in range(n)]),
        "flight_level": where(reply, (rng.integers(0, 1600, n) / 4).tolist()),
        "flight_status": where(reply, rng.integers(0, 2, n).tolist()),
    }
    for flag in ("mode_3a_not_validated", "mode_3a_garbled", "mode_3a_smoothed",
                 "flight_level_not_validated", "flight_level_garbled", "spi"):  # fmt: skip
        cols[flag] = (rng.random(n) < 0.01).tolist()
    for q in DOWNLINKED:
        hi = q.hi * 0.999
        cols[q.name] = where(ehs, rng.uniform(q.lo, hi, n).tolist())
    return cols


def rate(fn, seconds: float) -> float:
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        fn()
        n += 1
    return n / (time.perf_counter() - t0)


def identity_rate(data: bytes, n: int = 200) -> float:
    """Batches/s of the tracker's identity view of freshly decoded batches (their column
    arrays not yet cached, as in the service: decoding is timed apart)."""
    from skyfuse.fusion.tracker.identity import plot_identity

    fresh = [PlotBatch.from_json_bytes(data) for _ in range(n)]
    t0 = time.perf_counter()
    for f in fresh:
        plot_identity(f.column)
    return n / (time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--plots", type=int, default=500)
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--secondary", action="store_true", help="with the identity columns")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    b = make_batch(a.plots, secondary=a.secondary)
    data = b.to_json_bytes()
    enc = rate(b.to_json_bytes, a.seconds)
    dec = rate(lambda: PlotBatch.from_json_bytes(data), a.seconds)
    res = {
        "plots_per_batch": a.plots,
        "secondary_columns": a.secondary,
        "payload_bytes": len(data),
        "encode_batches_per_s": round(enc, 1),
        "decode_batches_per_s": round(dec, 1),
        "encode_plots_per_s": round(enc * a.plots),
        "decode_plots_per_s": round(dec * a.plots),
        "python": platform.python_version(),
        "machine": platform.machine(),
    }
    if a.secondary:
        res["identity_batches_per_s"] = round(identity_rate(data), 1)
    for k, v in res.items():
        print(f"{k:24s} {v}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=2)


if __name__ == "__main__":
    main()
