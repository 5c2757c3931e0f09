"""Survey of the LEBL surface recordings: what the fusion of ADS-B, multilateration and
surface movement radar can rest on.

Per file (CAT010 MLAT / SMR, CAT021 ADS-B): records per message type, time span and
wraps, decoding speed, identities (Mode-S addresses, track numbers), field shares,
update interval per target, ground-bit share, quality indicators (CAT021 NUCp/NUCr and
the σ they map to, CAT010 I500), the status messages (update-cycle period, I550), the
I200/I202 velocity consistency. Across sensors of the same day: aircraft seen by MLAT
and ADS-B (same address) with the MLAT − ADS-B position offset (ADS-B interpolated to
the MLAT time, both in the east/north plane of the MLAT reference point) and the time
offset that explains the along-track part of it; SMR plots against the nearest MLAT
report.

Usage: ``python benchmarks/asterix_survey.py [--data ../shared/data] [--out FILE.json]``
(default ``benchmarks/results/lebl_survey.json``).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import pymap3d
from scipy.spatial import cKDTree
from skyfuse.services.asterix import cat010, cat021, read_reports
from skyfuse.services.asterix.surveillance import columns

ROOT = Path(__file__).resolve().parents[1]
MLAT_REF = (41.29706278, 2.07844722, 4.0)  # SAC 0 / SIC 107: I042 is relative to it
SMR_SITE = (41.29561833, 2.09511417, 4.0)  # SAC 0 / SIC 7
DAYS = {
    "20160510": (dt.date(2016, 5, 10), ("mlat", "smr", "adsb")),
    "20201002": (dt.date(2020, 10, 2), ("mlat", "smr")),
}
REPORT_FIELDS_010 = (
    "typ rho_m x_m lat ground_speed_ms vx_ms ax track_number mode_3a mode_s callsign "
    "flight_level height_m length_m orientation_deg sigma_x_m"
).split()
REPORT_FIELDS_021 = (
    "flight_level geometric_height_m nucp nacp nac_v ground_speed_ms vertical_rate_ms "
    "callsign mode_3a emitter_category"
).split()


def quantiles(x, qs=(0.1, 0.5, 0.9)) -> dict:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    if not len(x):
        return {"n": 0}
    return {"n": len(x), **{f"p{round(q * 100)}": float(np.quantile(x, q)) for q in qs}}


def per_target_intervals(keys: np.ndarray, t_s: np.ndarray) -> dict:
    """Median interval between consecutive reports of each target, then its spread
    over targets (targets with ≥ 5 reports)."""
    medians = []
    for k in np.unique(keys[np.isfinite(keys)]):
        tk = np.sort(t_s[keys == k])
        if len(tk) >= 5:
            medians.append(np.median(np.diff(tk)))
    return quantiles(medians)


def time_checks(t_ns: np.ndarray) -> dict:
    d = np.diff(t_ns) / 1e9
    return {
        "first_utc": str(np.datetime64(int(t_ns.min()), "ns")),
        "last_utc": str(np.datetime64(int(t_ns.max()), "ns")),
        "span_s": float((t_ns.max() - t_ns.min()) / 1e9),
        "backward_steps": int(np.sum(d < 0)),
        "largest_backward_step_s": float(-d.min()) if len(d) and d.min() < 0 else 0.0,
        "largest_gap_s": float(d.max()) if len(d) else 0.0,
    }


def shares(reports, fields) -> dict:
    n = max(len(reports), 1)
    return {f: round(sum(getattr(r, f) is not None for r in reports) / n, 4) for f in fields}


def status_summary(statuses) -> dict:
    out: dict = {}
    for mtype in sorted({s.message_type for s in statuses}):
        t = np.array([s.tod for s in statuses if s.message_type == mtype])
        out[f"type_{mtype}"] = {"count": len(t), "interval_s": quantiles(np.diff(t))}
    i550 = Counter(
        (s.nogo, s.overload, s.time_source_invalid, s.test_target_failure)
        for s in statuses
        if s.nogo is not None
    )
    out["i550_nogo_ovl_tsv_ttf"] = {str(k): v for k, v in i550.items()}
    return out


def velocity_consistency(reps) -> dict:
    """I200 track angle against the direction of I202 (VX east, VY north) and against
    the direction of the reported x/y positions (differences along each track)."""
    c = columns(reps, ("track_number", "time_ns", "x_m", "y_m", "vx_ms", "vy_ms"))
    gs = columns(reps, ("ground_speed_ms", "track_angle_deg"))
    moving = np.isfinite(gs["ground_speed_ms"]) & (gs["ground_speed_ms"] > 5.0)
    dir_202 = np.degrees(np.arctan2(c["vx_ms"], c["vy_ms"])) % 360.0

    def diff(a, b):
        return np.abs((a - b + 180.0) % 360.0 - 180.0)

    d_200_202 = diff(gs["track_angle_deg"], dir_202)[moving]
    pos_dir, v_dir, a_dir = [], [], []
    for trk in np.unique(c["track_number"][np.isfinite(c["track_number"])]):
        m = (c["track_number"] == trk) & moving & np.isfinite(c["x_m"])
        idx = np.flatnonzero(m)
        if len(idx) < 3:
            continue
        dx, dy = np.diff(c["x_m"][idx]), np.diff(c["y_m"][idx])
        ok = np.hypot(dx, dy) > 10.0
        pos_dir.append((np.degrees(np.arctan2(dx, dy)) % 360.0)[ok])
        v_dir.append(dir_202[idx[1:]][ok])
        a_dir.append(gs["track_angle_deg"][idx[1:]][ok])
    if not pos_dir:
        return {"moving_reports": int(moving.sum())}
    pos_dir, v_dir, a_dir = map(np.concatenate, (pos_dir, v_dir, a_dir))
    return {
        "moving_reports": int(moving.sum()),
        "i200_vs_i202_deg": quantiles(d_200_202),
        "i202_vs_position_track_deg": quantiles(diff(v_dir, pos_dir)),
        "i200_vs_position_track_deg": quantiles(diff(a_dir, pos_dir)),
        "speed_ratio_i202_over_i200": quantiles(
            (np.hypot(c["vx_ms"], c["vy_ms"]) / gs["ground_speed_ms"])[moving]
        ),
    }


def field_monitors(reps) -> dict:
    """Reports with I020 RAB = 1 come from fixed transponders (field monitors): their
    scatter is the sensor's own position noise at that place."""
    out = {}
    for addr in sorted({r.mode_s for r in reps if r.rab and r.mode_s is not None}):
        xy = np.array([(r.x_m, r.y_m) for r in reps if r.rab and r.mode_s == addr], dtype=float)
        out[f"{addr:06X}"] = {
            "reports": len(xy),
            "mean_x_m": float(xy[:, 0].mean()),
            "mean_y_m": float(xy[:, 1].mean()),
            "std_x_m": float(xy[:, 0].std()),
            "std_y_m": float(xy[:, 1].std()),
        }
    return out


def survey_cat010(reports) -> dict:
    reps = [r for r in reports if isinstance(r, cat010.Cat010Report)]
    with_pos = [r for r in reps if r.x_m is not None or r.rho_m is not None]
    stats = [r for r in reports if isinstance(r, cat010.Cat010Status)]
    c = columns(with_pos, ("time_ns", "mode_s", "track_number"))
    t_s = c["time_ns"] / 1e9
    out = {
        "target_reports": len(reps),
        "track_ends": len(reps) - len(with_pos),
        "status_messages": status_summary(stats),
        "typ": dict(Counter(cat010.REPORT_TYPES.get(r.typ, str(r.typ)) for r in reps)),
        "target_type": dict(Counter(str(r.target_type) for r in reps)),
        "ground_bit_share": round(sum(r.ground for r in with_pos) / max(len(with_pos), 1), 4),
        "field_monitor_reports": sum(r.rab for r in reps),
        "field_monitors": field_monitors(with_pos),
        "distinct_mode_s": len(np.unique(c["mode_s"][np.isfinite(c["mode_s"])])),
        "distinct_track_numbers": len(np.unique(c["track_number"])),
        "field_shares": shares(with_pos, REPORT_FIELDS_010),
        "interval_per_track_s": per_target_intervals(c["track_number"], t_s),
        "interval_per_address_s": per_target_intervals(c["mode_s"], t_s),
        "velocity": velocity_consistency(with_pos),
    }
    sig = [r.sigma_x_m for r in with_pos if r.sigma_x_m is not None]
    out["i500_sigma_x_m"] = quantiles(sig)
    sizes = [r.length_m for r in with_pos if r.length_m is not None]
    out["i270_length_m"] = quantiles(sizes)
    return out


def survey_cat021(reports) -> dict:
    reps = [r for r in reports if isinstance(r, cat021.Cat021Report)]
    c = columns(reps, ("time_ns", "address"))
    ground = [r for r in reps if r.ground]
    return {
        "reports": len(reps),
        "editions": dict(Counter(r.edition for r in reps)),
        "distinct_addresses": len(np.unique(c["address"])),
        "ground_bit_share": round(len(ground) / max(len(reps), 1), 4),
        "field_shares": shares(reps, REPORT_FIELDS_021),
        "nucp": dict(sorted(Counter(str(r.nucp) for r in reps).items())),
        "nucr": dict(sorted(Counter(str(r.nac_v) for r in reps).items())),
        "sigma_pos_m": quantiles([r.sigma_pos_m for r in reps if r.sigma_pos_m is not None]),
        "nucp_on_ground": dict(Counter(str(r.nucp) for r in ground)),
        "interval_per_address_s": per_target_intervals(c["address"], c["time_ns"] / 1e9),
        "address_types": dict(Counter(str(r.address_type) for r in reps)),
    }


def enu(lat, lon, ref=MLAT_REF) -> tuple[np.ndarray, np.ndarray]:
    """East/north (m) in the tangent plane of ``ref`` of points at the reference height."""
    e, n, _ = pymap3d.geodetic2enu(np.asarray(lat), np.asarray(lon), ref[2], *ref)
    return np.asarray(e), np.asarray(n)


def mlat_vs_adsb(mlat_reports, adsb_reports, max_gap_s: float = 3.0) -> dict:
    """MLAT − ADS-B (interpolated to the MLAT time) per common address: position offset
    and the along-track part as a time offset τ = (d · v) / |v|² (τ > 0: the MLAT
    position is ahead of the ADS-B position of the same time stamp)."""
    m = [r for r in mlat_reports if isinstance(r, cat010.Cat010Report) and r.x_m is not None]
    a_by = defaultdict(list)
    for r in adsb_reports:
        a_by[r.address].append(r)
    m_addr = {r.mode_s for r in m if r.mode_s is not None}
    common = sorted(m_addr & set(a_by))
    rows = []
    for addr in common:
        a = sorted(a_by[addr], key=lambda r: r.time_ns)
        ta = np.array([r.time_ns for r in a]) / 1e9
        ea, na = enu([r.lat for r in a], [r.lon for r in a])
        va = columns(a, ("v_east_ms", "v_north_ms"))
        for r in (r for r in m if r.mode_s == addr):
            t = r.time_ns / 1e9
            k = np.searchsorted(ta, t)
            if k == 0 or k == len(ta) or ta[k] - ta[k - 1] > max_gap_s:
                continue
            w = (t - ta[k - 1]) / (ta[k] - ta[k - 1])
            e = ea[k - 1] + w * (ea[k] - ea[k - 1])
            n = na[k - 1] + w * (na[k] - na[k - 1])
            v = (va["v_east_ms"][k], va["v_north_ms"][k])
            rows.append((r.x_m - e, r.y_m - n, v[0], v[1], r.ground, addr))
    if not rows:
        return {"common_addresses": len(common)}
    d = np.array([row[:5] for row in rows], dtype=float)
    speed = np.hypot(d[:, 2], d[:, 3])
    out = {
        "mlat_addresses": len(m_addr),
        "adsb_addresses": len(a_by),
        "common_addresses": len(common),
        "pairs": len(rows),
        "addresses_with_pairs": len({row[5] for row in rows}),
    }
    for name, sel in (("ground", d[:, 4] == 1), ("airborne", d[:, 4] == 0)):
        if not sel.any():
            continue
        dist = np.hypot(d[sel, 0], d[sel, 1])
        out[name] = {
            "pairs": int(sel.sum()),
            "mean_east_m": float(np.mean(d[sel, 0])),
            "mean_north_m": float(np.mean(d[sel, 1])),
            "distance_m": quantiles(dist),
        }
    fast = speed > 30.0
    if fast.any():
        tau = (d[fast, 0] * d[fast, 2] + d[fast, 1] * d[fast, 3]) / speed[fast] ** 2
        cross = (d[fast, 0] * d[fast, 3] - d[fast, 1] * d[fast, 2]) / speed[fast]
        out["moving_over_30_ms"] = {
            "pairs": int(fast.sum()),
            "time_offset_s": quantiles(tau),
            "cross_track_m": quantiles(cross),
        }
    return out


def smr_vs_mlat(smr_reports, mlat_reports, gate_m: float = 25.0) -> dict:
    """Each SMR plot (x/y of the SMR site, moved to the MLAT reference plane) against the
    nearest MLAT report within ±1 s: distance, and the mean SMR − MLAT offset of the
    pairs inside ``gate_m``; MLAT addresses seen by the SMR (≥ 5 pairs)."""
    s = [r for r in smr_reports if isinstance(r, cat010.Cat010Report) and r.x_m is not None]
    m = [r for r in mlat_reports if isinstance(r, cat010.Cat010Report) and r.x_m is not None]
    sc = columns(s, ("time_ns", "x_m", "y_m"))
    lat, lon, _ = pymap3d.enu2geodetic(sc["x_m"], sc["y_m"], 0.0, *SMR_SITE)
    se, sn = enu(lat, lon)
    mc = columns(m, ("time_ns", "x_m", "y_m", "mode_s"))
    mb = np.floor(mc["time_ns"] / 1e9).astype(np.int64)
    sb = np.floor(sc["time_ns"] / 1e9).astype(np.int64)
    dist = np.full(len(s), np.inf)
    offs, seen = [], Counter()
    for b in np.unique(sb):
        cand = np.flatnonzero(np.abs(mb - b) <= 1)
        if not len(cand):
            continue
        tree = cKDTree(np.column_stack([mc["x_m"][cand], mc["y_m"][cand]]))
        idx = np.flatnonzero(sb == b)
        dd, jj = tree.query(np.column_stack([se[idx], sn[idx]]))
        dist[idx] = dd
        for i, dij, j in zip(idx, dd, jj, strict=True):
            if dij < gate_m:
                offs.append((se[i] - mc["x_m"][cand[j]], sn[i] - mc["y_m"][cand[j]]))
                if np.isfinite(mc["mode_s"][cand[j]]):
                    seen[int(mc["mode_s"][cand[j]])] += 1
    offs = np.array(offs) if offs else np.zeros((0, 2))
    return {
        "smr_plots": len(s),
        "nearest_mlat_m": quantiles(dist[np.isfinite(dist)]),
        f"share_within_{gate_m:g}_m": float(np.mean(dist < gate_m)) if len(s) else 0.0,
        "mean_offset_east_m": float(offs[:, 0].mean()) if len(offs) else None,
        "mean_offset_north_m": float(offs[:, 1].mean()) if len(offs) else None,
        "mlat_addresses_seen_by_smr": sum(1 for v in seen.values() if v >= 5),
    }


def survey_file(path: Path, date: dt.date) -> tuple[dict, list]:
    t0 = time.perf_counter()
    reports, stats, messages = read_reports(path, date=date)
    seconds = time.perf_counter() - t0
    records = sum(v for k, v in stats.items() if k.endswith("_records"))
    kinds = Counter(
        f"type_{r.message_type}" if isinstance(r, cat010.Cat010Status) else type(r).__name__
        for r in reports
    )
    sensors = Counter(f"{r.sac}/{r.sic}" for r in reports)
    t_ns = np.array([r.time_ns for r in reports], dtype=np.int64)
    out = {
        "file": path.name,
        "bytes": path.stat().st_size,
        "records": records,
        "decode_s": round(seconds, 3),
        "records_per_s": round(records / seconds),
        "sensors": dict(sensors),
        "kinds": dict(kinds),
        "reader_counts": stats,
        "messages": messages[:5],
        "time": time_checks(t_ns),
    }
    if any(isinstance(r, cat021.Cat021Report) for r in reports):
        out["adsb"] = survey_cat021(reports)
    else:
        out["cat010"] = survey_cat010(reports)
    return out, reports


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    ap.add_argument(
        "--out", type=Path, default=ROOT / "benchmarks" / "results" / "lebl_survey.json"
    )
    args = ap.parse_args()
    result: dict = {"files": {}, "cross": {}}
    for day, (date, kinds) in DAYS.items():
        got = {}
        for kind in kinds:
            start = {"20160510": "2200_2215", "20201002": "0800_0815"}[day]
            path = args.data / f"lebl_{day}_{start}_{kind}.ast"
            if not path.exists():
                continue
            summary, got[kind] = survey_file(path, date)
            result["files"][path.name] = summary
            print(f"{path.name}: {summary['records']} records, {summary['records_per_s']}/s")
        cross: dict = {}
        if "mlat" in got and "adsb" in got:
            cross["mlat_vs_adsb"] = mlat_vs_adsb(got["mlat"], got["adsb"])
        if "mlat" in got and "smr" in got:
            cross["smr_vs_mlat"] = smr_vs_mlat(got["smr"], got["mlat"])
        result["cross"][day] = cross
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2, default=str) + "\n")
    print(json.dumps(result["cross"], indent=2))
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
