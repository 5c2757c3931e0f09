"""Named scenarios (values from the sources; ambiguous values are parameters).

* ``thesis-stt`` ([thesis] §7.3): one target from x₀ = [100, 16, 100, 4] (m, m/s),
  T = 1 s, 50 scans, P_D = 0.6, R = 25 I. Clutter: the 900 × 900 m area is split at
  x = 333.3 m into a weak region [0, 333.3] × [0, 900] (2e-5 m⁻², area 3.0e5 m², ≈6 per
  scan) and a strong one [333.3, 900] × [0, 900] (2e-4 m⁻², 5.1e5 m², ≈102 per scan): the
  target starts in weak clutter and enters the strong region at t ≈ 14.6 s. Truth process
  noise q = 0.75 ([thesis] §7.3: truth per (7.2), q = 0.75; q = 0 gives the straight
  line through (900, 300) at scan 50).
* ``thesis-mtt-5/-15/-50`` ([thesis] §7.4): 1000 × 1000 m, centre (500, 500); targets start
  R₀ = 500 m out (475 m at scan 1), fly inward at 25 m/s, cross the centre at scan 20;
  spacing 10° (7° for 50); per-run velocity noise σ_v = √50/20 m/s per axis; P_D = 0.8,
  R = 25 I, 40 scans, clutter 0 (parameter ``clutter_density``).
* ``lm-ipf-2/-15`` ([LM-IPF], simulations): start on r = 450 m, 20°/10° apart, fly straight through
  c + δ, δ ~ N(0, 2R), at scan 20 (22.5 m/s nominal); the trajectories depend only on
  ``trajectory_seed`` (default 0), the same in every run.
* ``crossing-4g`` ([MZD] §2, §4): one radar at the plane origin (2d by default, σ_r = 20 m,
  σ_θ = 2.5 mrad, T = 4 s), two targets 50 km out at azimuths 45° and 46.1° flying at
  311 m/s towards it, opposite 4 g turns (each towards the other) from 34 to 42 s, so
  they cross at ≈38 s; 72 s.
* ``regional``: 4 radars at airport reference points (Beograd LYBE 3d 4 s, Vršac LYVR 2d
  8 s, Timișoara LRTR 2d 10 s, Novi Sad 3d 12 s; 62-137 km apart), stereographic system
  plane at their mean position; overflights with turning waypoints, climbs and descents,
  arrivals landing at and departures climbing out of Beograd; some airborne at t = 0,
  others entering, some leaving or landing during the run; Mode-S on 80% of them, with
  callsigns, flight levels, a few code changes and garbled replies, half of them
  downlinking their track and turn (:mod:`fusion.sim.identity`); uniform clutter plus a
  ground-clutter ring around each radar; horizon test at 0°; optionally an ADS-B network
  and a multilateration at Beograd (``adsb``, ``mlat``: :mod:`fusion.sim.report_sites`).

Scan numbering of the planar thesis scenarios follows the thesis: scan k (k = 1..K) is a
snapshot at t = k·T after the scenario start, and the targets' initial states are at
t = 0 (so thesis-stt with q = 0 is at (900, 300) at scan 50, and the thesis-mtt / lm-ipf
targets are at the centre at scan 20). Polar radars number their revolutions from 0.

Randomness: the *trajectory* generator is seeded from ``seed`` (stream 0 of
``SeedSequence(seed)``), except for lm-ipf whose trajectories use ``trajectory_seed``
([LM-IPF]: the same trajectories in every run, new measurements per run). The
:class:`~fusion.sim.Simulator` draws measurements from independent streams of its own
seed (one per sensor), so changing one sensor never changes another's plots.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from skyfuse.fusion.frames import Stereographic
from skyfuse.schemas import FrameKind, FrameSpec, RadarSite

from .identity import IdentityParams, assign_identities, identity_rng
from .report_sites import REPORT_PARAMETERS, report_sensors
from .scenario import (
    DEFAULT_START_TIME,
    Param,
    Scenario,
    coerce,
    in_range,
    non_negative,
    positive,
    probability,
)
from .sensor import AnnulusRegion, RectRegion, SensorConfig
from .site_bias import apply_site_biases, bias_parameters
from .trajectories import G0, TargetSet, TrajectoryBuilder

FT = 0.3048

_COMMON = {
    "start_time": Param(
        DEFAULT_START_TIME, "scenario epoch, ns UTC or ISO-8601 (default 2026-01-01T00:00:00Z)"
    ),
    "truth_period": Param(
        0.0, "truth message period, s (0 = scan period of the first sensor)", non_negative
    ),
}
_PLANAR = {
    "lat0": Param(44.8, "latitude of the scenario plane origin, deg", in_range(-89.0, 89.0)),
    "lon0": Param(20.45, "longitude of the scenario plane origin, deg", in_range(-180.0, 180.0)),
}


def _cartesian_common(pd: float) -> dict[str, Param]:
    return {
        "p_detection": Param(pd, "detection probability P_D", probability),
        "sigma": Param(5.0, "measurement noise σ per axis, m (R = σ² I; [thesis]: 25 I)", positive),
        "scan_period": Param(1.0, "scan period T, s", positive),
        "clutter_density": Param(
            0.0, "uniform Poisson clutter over the area, plots per m² per scan", in_range(0, 1)
        ),
    }


def _trajectory_rng(seed: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(0,)))


def _cartesian_sensor(p: dict, area: tuple[float, float, float, float], regions=()) -> list:
    x0, x1, y0, y1 = area
    site = RadarSite(
        radar_id="sensor",
        name="planar cartesian sensor",
        lat=p["lat0"],
        lon=p["lon0"],
        alt=0.0,
        kind="cartesian",
        sigma_cartesian=p["sigma"],
        scan_period=p["scan_period"],
        p_detection=p["p_detection"],
        max_range=float(math.hypot(max(abs(x0), abs(x1)), max(abs(y0), abs(y1)))) + 1.0,
        clutter_density=p["clutter_density"],
        n_sectors=1,
    )
    return [SensorConfig(site=site, phase=0.0, first_scan=1, coverage=area, regions=tuple(regions))]


@functools.lru_cache(maxsize=32)
def _plane(lat0: float, lon0: float) -> Stereographic:
    """Projections are cached: building the pyproj transformers costs ≈0.1 s, which would
    dominate Monte Carlo loops that build a scenario per run."""
    return Stereographic(lat0, lon0)


def _planar_frame(p: dict) -> tuple[FrameSpec, Stereographic]:
    return (
        FrameSpec(kind=FrameKind.PLANAR, lat0=p["lat0"], lon0=p["lon0"]),
        _plane(p["lat0"], p["lon0"]),
    )


# ------------------------------------------------------------------------------------
# thesis-stt ([thesis] §7.3)
# ------------------------------------------------------------------------------------
_STT_PARAMS = {
    **_PLANAR,
    **_cartesian_common(0.6),
    "x0": Param(100.0, "initial x, m"),
    "y0": Param(100.0, "initial y, m"),
    "vx0": Param(16.0, "initial x velocity, m/s"),
    "vy0": Param(4.0, "initial y velocity, m/s"),
    "q": Param(
        0.75,
        "truth process-noise intensity q, (m/s²)²: white acceleration, constant over each "
        "scan interval, Q_T = q [[T⁴/4, T³/2], [T³/2, T²]] ([thesis] §7.3: q = 0.75, [A]); "
        "0 = straight line to (900, 300)",
        non_negative,
    ),
    "area": Param(900.0, "side of the square surveillance area [0, area]², m", positive),
    "split_x": Param(
        900.0 / 2.7,
        "x where the weak clutter region [0, split_x] × [0, area] meets the strong one "
        "[split_x, area] × [0, area], m (default: areas 3.0e5 and 5.1e5 m²)",
        positive,
    ),
    "weak_density": Param(
        2e-5, "weak clutter region density, m⁻² per scan (≈6/scan)", in_range(0, 1)
    ),
    "strong_density": Param(
        2e-4, "strong clutter region density, m⁻² per scan (≈102/scan)", in_range(0, 1)
    ),
}


def _build_stt(p: dict, seed: int, duration: float, n: int) -> tuple:
    if n != 1:
        raise ValueError(f"scenario 'thesis-stt': parameter 'targets' = {n}: must be 1")
    if not 0 < p["split_x"] < p["area"]:
        raise ValueError(
            f"scenario 'thesis-stt': parameter 'split_x' = {p['split_x']}: must be inside "
            f"(0, area = {p['area']})"
        )
    rng = _trajectory_rng(seed)
    T = p["scan_period"]
    b = TrajectoryBuilder(0.0, (p["x0"], p["y0"], 0.0), (p["vx0"], p["vy0"], 0.0))
    if p["q"] > 0:
        n_steps = math.ceil(duration / T)
        acc = rng.normal(0.0, math.sqrt(p["q"]), (n_steps, 2))
        for a in acc:
            b.accelerate(T, (a[0], a[1], 0.0))
    targets = TargetSet.from_builders([b])
    a, s = p["area"], p["split_x"]
    regions = [
        RectRegion(0.0, s, 0.0, a, p["weak_density"]),
        RectRegion(s, a, 0.0, a, p["strong_density"]),
    ]
    return targets, _cartesian_sensor(p, (0.0, a, 0.0, a), regions), *_planar_frame(p)


# ------------------------------------------------------------------------------------
# thesis-mtt-N ([thesis] §7.4)
# ------------------------------------------------------------------------------------
def _mtt_params(spacing: float) -> dict[str, Param]:
    return {
        **_PLANAR,
        **_cartesian_common(0.8),
        "area": Param(1000.0, "side of the square area [0, area]², m (clutter coverage)", positive),
        "r0": Param(
            500.0, "start radius R₀ (at t = 0), m; centre reached at t = r0/speed", positive
        ),
        "speed": Param(25.0, "inward speed v, m/s", positive),
        "spacing_deg": Param(spacing, "angular spacing Δθ of the start points, deg", positive),
        "arc_center_deg": Param(
            90.0, "direction of the middle of the start arc, deg counter-clockwise from east"
        ),
        "sigma_v": Param(
            math.sqrt(50.0) / 20.0,
            "velocity randomisation σ_v per axis, m/s, once per run (√(2R)/20: variance 2R "
            "= 50 m² per axis at the centre crossing)",
            non_negative,
        ),
    }


def _arc_angles(n: int, spacing_deg: float, centre_deg: float) -> np.ndarray:
    return np.radians(centre_deg + (np.arange(n) - (n - 1) / 2.0) * spacing_deg)


def _build_mtt(p: dict, seed: int, duration: float, n: int) -> tuple:
    rng = _trajectory_rng(seed)
    c = 0.5 * p["area"]
    th = _arc_angles(n, p["spacing_deg"], p["arc_center_deg"])
    u = np.column_stack([np.cos(th), np.sin(th)])
    dv = rng.normal(0.0, p["sigma_v"], (n, 2))
    builders = []
    for i in range(n):
        pos = (c + p["r0"] * u[i, 0], c + p["r0"] * u[i, 1], 0.0)
        vel = (-p["speed"] * u[i, 0] + dv[i, 0], -p["speed"] * u[i, 1] + dv[i, 1], 0.0)
        builders.append(TrajectoryBuilder(0.0, pos, vel))
    a = p["area"]
    return (
        TargetSet.from_builders(builders),
        _cartesian_sensor(p, (0.0, a, 0.0, a)),
        *_planar_frame(p),
    )


# ------------------------------------------------------------------------------------
# lm-ipf-N ([LM-IPF], simulations)
# ------------------------------------------------------------------------------------
def _lmipf_params(spacing: float) -> dict[str, Param]:
    return {
        **_PLANAR,
        **_cartesian_common(0.8),
        "area": Param(1000.0, "side of the square area [0, area]², m", positive),
        "radius": Param(450.0, "start circle radius, m", positive),
        "speed": Param(22.5, "nominal inward speed, m/s (centre at t = radius/speed)", positive),
        "spacing_deg": Param(spacing, "angular separation of the start points, deg", positive),
        "arc_center_deg": Param(
            90.0, "direction of the middle of the start arc, deg counter-clockwise from east"
        ),
        "delta_var": Param(
            50.0, "variance per axis of the centre-crossing offset δ ~ N(0, 2R), m²", non_negative
        ),
        "trajectory_seed": Param(
            0, "seed of the trajectories (fixed over runs; measurements use `seed`)"
        ),
    }


def _build_lmipf(p: dict, seed: int, duration: float, n: int) -> tuple:
    rng = _trajectory_rng(p["trajectory_seed"])
    c = 0.5 * p["area"]
    tc = p["radius"] / p["speed"]
    th = _arc_angles(n, p["spacing_deg"], p["arc_center_deg"])
    delta = rng.normal(0.0, math.sqrt(p["delta_var"]), (n, 2))
    builders = []
    for i in range(n):
        p0 = np.array([c + p["radius"] * math.cos(th[i]), c + p["radius"] * math.sin(th[i])])
        v = (np.array([c, c]) + delta[i] - p0) / tc
        builders.append(TrajectoryBuilder(0.0, (p0[0], p0[1], 0.0), (v[0], v[1], 0.0)))
    a = p["area"]
    return (
        TargetSet.from_builders(builders),
        _cartesian_sensor(p, (0.0, a, 0.0, a)),
        *_planar_frame(p),
    )


# ------------------------------------------------------------------------------------
# crossing-4g ([MZD] §2, §4)
# ------------------------------------------------------------------------------------
_CROSS_PARAMS = {
    **_PLANAR,
    "radar_kind": Param(
        "2d", "radar kind: 2d (range, azimuth, altitude) or 3d", choices=("2d", "3d")
    ),
    "sigma_range": Param(20.0, "σ_r, m", positive),
    "sigma_az_mrad": Param(2.5, "σ_θ, mrad ([MZD] cases: 2.5 and 6)", positive),
    "sigma_el_mrad": Param(4.0, "σ_elevation (3d), mrad", positive),
    "sigma_altitude": Param(30.0, "altitude (Mode C) noise σ (2d), m", positive),
    "scan_period": Param(4.0, "antenna revolution period T, s", positive),
    "n_sectors": Param(16, "sector batches per revolution", in_range(1, 360)),
    "p_detection": Param(1.0, "detection probability P_D", probability),
    "clutter_density": Param(0.0, "uniform Poisson clutter, plots per m² per scan", in_range(0, 1)),
    "max_range": Param(100_000.0, "radar maximum range, m", positive),
    "range0": Param(50_000.0, "initial ground distance of the targets from the radar, m", positive),
    "azimuth1_deg": Param(45.0, "initial azimuth of target 0, deg clockwise from north"),
    "azimuth2_deg": Param(46.1, "initial azimuth of target 1, deg clockwise from north"),
    "speed": Param(311.0, "speed, m/s (towards the radar)", positive),
    "altitude": Param(3000.0, "flight height above the ellipsoid, m", in_range(0, 30000)),
    "g_load": Param(4.0, "turn lateral acceleration, g", positive),
    "turn_start": Param(34.0, "turn start, s", non_negative),
    "turn_end": Param(42.0, "turn end, s", non_negative),
}


def _build_crossing(p: dict, seed: int, duration: float, n: int) -> tuple:
    if n != 2:
        raise ValueError(f"scenario 'crossing-4g': parameter 'targets' = {n}: must be 2")
    if p["turn_end"] < p["turn_start"]:
        raise ValueError(
            f"scenario 'crossing-4g': parameter 'turn_end' = {p['turn_end']}: must be >= "
            f"turn_start = {p['turn_start']}"
        )
    site = RadarSite(
        radar_id="radar",
        name="crossing-4g radar",
        lat=p["lat0"],
        lon=p["lon0"],
        alt=0.0,
        kind=p["radar_kind"],
        sigma_range=p["sigma_range"],
        sigma_azimuth=p["sigma_az_mrad"] * 1e-3,
        sigma_elevation=p["sigma_el_mrad"] * 1e-3,
        sigma_altitude=p["sigma_altitude"],
        scan_period=p["scan_period"],
        p_detection=p["p_detection"],
        max_range=p["max_range"],
        clutter_density=p["clutter_density"],
        n_sectors=p["n_sectors"],
    )
    # Target 1 is clockwise of target 0, i.e. on target 0's left when both fly towards the
    # radar: target 0 turns left, target 1 right, so the trajectories cross.
    omega = p["g_load"] * G0 / p["speed"]
    builders = []
    for az_deg, sign in ((p["azimuth1_deg"], 1.0), (p["azimuth2_deg"], -1.0)):
        az = math.radians(az_deg)
        e, nn = math.sin(az), math.cos(az)
        b = TrajectoryBuilder(
            0.0,
            (p["range0"] * e, p["range0"] * nn, p["altitude"]),
            (-p["speed"] * e, -p["speed"] * nn, 0.0),
        )
        b.straight(p["turn_start"]).turn(p["turn_end"] - p["turn_start"], sign * omega)
        builders.append(b)
    return (
        TargetSet.from_builders(builders),
        [SensorConfig(site=site, phase=0.0)],
        *_planar_frame(p),
    )


# ------------------------------------------------------------------------------------
# regional: real sites, air traffic
# ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _RegionalRadar:
    radar_id: str
    name: str
    lat: float
    lon: float
    alt: float
    kind: str
    scan_period: float
    sigma_range: float
    sigma_azimuth: float
    max_range: float
    phase_fraction: float


_REGIONAL_RADARS = (
    # Airport reference points (WGS-84, approximate), antenna 20 m above the field.
    _RegionalRadar("LYBE", "Beograd Nikola Tesla", 44.8184, 20.3091, 122.0, "3d", 4.0,
                   40.0, 0.0015, 180_000.0, 0.0),
    _RegionalRadar("LYVR", "Vršac", 45.1469, 21.3099, 104.0, "2d", 8.0,
                   60.0, 0.0025, 200_000.0, 0.37),
    _RegionalRadar("LRTR", "Timișoara Traian Vuia", 45.8099, 21.3379, 126.0, "2d", 10.0,
                   70.0, 0.0030, 220_000.0, 0.61),
    _RegionalRadar("NOVISAD", "Novi Sad", 45.2671, 19.8335, 100.0, "3d", 12.0,
                   50.0, 0.0020, 200_000.0, 0.83),
    # two more for a six-radar network (docs/performance.md): Osijek and Szeged airports
    _RegionalRadar("LDOS", "Osijek", 45.4627, 18.8103, 110.0, "3d", 6.0,
                   45.0, 0.0018, 200_000.0, 0.12),
    _RegionalRadar("LHUD", "Szeged", 46.2467, 20.0911, 104.0, "2d", 5.0,
                   60.0, 0.0025, 200_000.0, 0.49),
)  # fmt: skip

_REGIONAL_PARAMS = {
    "radars": Param(
        4,
        "number of radars, the first N of LYBE 3d 4 s, LYVR 2d 8 s, LRTR 2d 10 s, NOVISAD "
        "3d 12 s, LDOS 3d 6 s, LHUD 2d 5 s",
        in_range(3, 6),
    ),
    "p_detection": Param(0.9, "detection probability of every radar", probability),
    "clutter_density": Param(
        3e-10, "uniform clutter over each radar's coverage, m⁻² per scan", in_range(0, 1)
    ),
    "ground_clutter_density": Param(
        2e-8, "extra clutter in a 2-25 km ring around each radar, m⁻² per scan", in_range(0, 1)
    ),
    "n_sectors": Param(16, "sector batches per revolution", in_range(1, 360)),
    "min_elevation_deg": Param(
        0.0, "radar horizon: minimum geometric elevation, deg", in_range(-90, 90)
    ),
    "sigma_elevation": Param(0.004, "3d radars' elevation σ, rad", positive),
    "sigma_altitude": Param(30.0, "2d radars' Mode C altitude σ, m", positive),
    "altitude_quantum_ft": Param(25.0, "2d altitude quantisation, ft (0 = none)", non_negative),
    "mode_s_fraction": Param(0.8, "fraction of aircraft with a Mode-S address", in_range(0, 1)),
    "code_change_fraction": Param(
        0.05,
        "fraction of aircraft with a code that get a new Mode-3/A code during the run",
        in_range(0, 1),
    ),
    "emergency_fraction": Param(
        0.0, "fraction of those code changes that are to 7700 (emergency)", in_range(0, 1)
    ),
    "ehs_fraction": Param(
        0.5,
        "fraction of Mode-S aircraft that downlink BDS 5,0/6,0 (enhanced surveillance)",
        in_range(0, 1),
    ),
    "garble_probability": Param(
        0.0,
        "probability that a reply's Mode-3/A code, or its flight level, is garbled (a garbled "
        "level leaves a 2-D radar's plot without altitude)",
        in_range(0, 1),
    ),
    "area_radius": Param(170_000.0, "radius of the traffic area around the centre, m", positive),
    "airborne_fraction": Param(
        0.6, "fraction of aircraft (not departures) already airborne at t = 0", in_range(0, 1)
    ),
    "traffic": Param(
        "mixed",
        "mixed: most aircraft in the air at t = 0, a third of them leaving during the run, "
        "departures and arrivals joining in the first 80 %; steady: each aircraft's route "
        "starts at a uniform time in (-route time, duration), so the expected number of "
        "aircraft in the air is the same at every instant (soak runs)",
        choices=("mixed", "steady"),
    ),
}


def _regional_routes(
    rng: np.random.Generator,
    n: int,
    duration: float,
    radius: float,
    airport_xy: np.ndarray,
    airborne_fraction: float,
    steady: bool = False,
):
    """Random aircraft: overflights crossing the area (with 1-3 turning waypoints, some
    climbing or descending), arrivals descending to the airport and departures climbing
    out of it, timed by :func:`_mixed_timing` or :func:`_steady_timing` (``steady``).
    Returns builders, birth and death times (s)."""
    builders, births, deaths = [], [], []
    for _ in range(n):
        kind = rng.choice(["over", "arr", "dep"], p=[0.7, 0.15, 0.15])
        speed = rng.uniform(150.0, 240.0)
        g_load = rng.uniform(0.4, 1.0)
        max_climb = rng.uniform(8.0, 15.0)
        cruise = 300.0 * round(rng.uniform(6000.0, 12000.0) / 300.0)
        beta = rng.uniform(0.0, 2 * math.pi)
        edge = radius * np.array([math.cos(beta), math.sin(beta)])
        runway = math.radians(120.0) + (math.pi if rng.random() < 0.5 else 0.0)
        rw = np.array([math.cos(runway), math.sin(runway)])
        if kind == "dep":
            start, start_alt = airport_xy.copy(), 300.0
            heading = rw
            end = edge
            wps = [(airport_xy + 15_000.0 * rw, 2500.0)]
            mid = 0.5 * (wps[0][0] + end) + rng.normal(0.0, 20_000.0, 2)
            wps += [(mid, cruise), (end, cruise)]
        else:
            start, start_alt = edge, (cruise if kind == "over" else rng.uniform(4000.0, 8000.0))
            if kind == "over":
                gamma = beta + math.pi + rng.uniform(-1.0, 1.0)
                end = radius * np.array([math.cos(gamma), math.sin(gamma)])
                n_mid = int(rng.integers(1, 4))
                wps = []
                for j in range(n_mid):
                    f = (j + 1) / (n_mid + 1)
                    pt = start + f * (end - start) + rng.normal(0.0, 25_000.0, 2)
                    alt = cruise
                    if rng.random() < 0.4:
                        alt = float(np.clip(cruise + rng.choice([-1, 1]) * rng.uniform(600, 2400),
                                            3000.0, 12500.0))  # fmt: skip
                    wps.append((pt, alt))
                wps.append((end, wps[-1][1]))
            else:  # arrival: to a final-approach fix 15 km out, then to the runway
                faf = airport_xy - 15_000.0 * rw
                mid = 0.5 * (start + faf) + rng.normal(0.0, 15_000.0, 2)
                wps = [(mid, 0.5 * (start_alt + 1500.0)), (faf, 1500.0), (airport_xy, 300.0)]
            to_first = wps[0][0] - start
            heading = to_first / np.linalg.norm(to_first)
        b = TrajectoryBuilder(0.0, (start[0], start[1], start_alt), (*(speed * heading), 0.0))
        for pt, alt in wps:
            b.fly_to(pt[0], pt[1], alt, g_load=g_load, max_climb_rate=max_climb)
        if steady:
            shift, birth = _steady_timing(rng, b.t, duration)
        else:
            shift, birth = _mixed_timing(rng, kind, b.t, duration, airborne_fraction)
        for s in b.segments:
            s.t0 += shift
        b.t += shift
        builders.append(b)
        births.append(birth)
        deaths.append(b.t)
    return builders, np.array(births), np.array(deaths)


def _mixed_timing(
    rng: np.random.Generator, kind: str, route_time: float, duration: float, airborne: float
) -> tuple[float, float]:
    """(time shift of the route, birth time) s: an arrival or overflight is in the air at
    t = 0 with probability ``airborne`` (a third of those leave or land during the run),
    the others and the departures start at a uniform time in the first 80 % of the run."""
    if kind != "dep" and rng.random() < airborne:
        if rng.random() < 0.35:
            remaining = rng.uniform(0.1, 0.9) * duration
        else:
            remaining = rng.uniform(duration, max(duration, route_time))
        return min(remaining, route_time) - route_time, 0.0
    shift = rng.uniform(0.0, 0.8 * duration)
    return shift, shift


def _steady_timing(
    rng: np.random.Generator, route_time: float, duration: float
) -> tuple[float, float]:
    """(time shift, birth time) s of a route of length L = ``route_time`` started at
    s ~ U(−L, duration): the aircraft is in the air at t ∈ [0, duration] with probability
    P(t − L ≤ s ≤ t) = L / (duration + L), the same at every t, so the expected traffic
    (and the plot rate) is stationary over the run."""
    shift = rng.uniform(-route_time, duration)
    return shift, max(shift, 0.0)


def _build_regional(p: dict, seed: int, duration: float, n: int) -> tuple:
    radars = _REGIONAL_RADARS[: p["radars"]]
    lat_c = float(np.mean([r.lat for r in radars]))
    lon_c = float(np.mean([r.lon for r in radars]))
    plane = _plane(lat_c, lon_c)
    frame = FrameSpec(kind=FrameKind.STEREOGRAPHIC, lat0=lat_c, lon0=lon_c)
    quantum = p["altitude_quantum_ft"] * FT
    sensors = []
    for r in radars:
        site = RadarSite(
            radar_id=r.radar_id,
            name=r.name,
            lat=r.lat,
            lon=r.lon,
            alt=r.alt,
            kind=r.kind,
            sigma_range=r.sigma_range,
            sigma_azimuth=r.sigma_azimuth,
            sigma_elevation=p["sigma_elevation"],
            sigma_altitude=p["sigma_altitude"],
            scan_period=r.scan_period,
            p_detection=p["p_detection"],
            min_range=500.0,
            max_range=r.max_range,
            clutter_density=p["clutter_density"],
            n_sectors=p["n_sectors"],
        )
        ring = AnnulusRegion(2_000.0, 25_000.0, 0.0, 2 * math.pi, p["ground_clutter_density"])
        sensors.append(
            SensorConfig(
                site=site,
                phase=r.phase_fraction * r.scan_period,
                min_elevation=math.radians(p["min_elevation_deg"]),
                altitude_quantum=quantum,
                regions=(ring,),
                report_mode_s=True,
                garble_probability=p["garble_probability"],
            )
        )
    rng = _trajectory_rng(seed)
    ax, ay = plane.forward(radars[0].lat, radars[0].lon)
    builders, births, deaths = _regional_routes(
        rng,
        n,
        duration,
        p["area_radius"],
        np.array([float(ax), float(ay)]),
        p["airborne_fraction"],
        steady=p["traffic"] == "steady",
    )
    has_mode_s = rng.random(n) < p["mode_s_fraction"]
    addresses = 1 + rng.choice((1 << 24) - 1, size=n, replace=False)  # unique, 24-bit, != 0
    squawks = rng.integers(0o1000, 0o7000, n)
    targets = TargetSet.from_builders(
        builders,
        t_birth=births,
        t_death=deaths,
        mode_s=np.where(has_mode_s, addresses, -1),
        mode_3a=np.where(has_mode_s, squawks, -1),
    )
    ident = IdentityParams(p["code_change_fraction"], p["emergency_fraction"], p["ehs_fraction"],
                           p["garble_probability"])  # fmt: skip
    assign_identities(targets, identity_rng(seed), duration, ident)
    sensors += report_sensors(p, (lat_c, lon_c), (radars[0].lat, radars[0].lon, radars[0].alt))
    return targets, sensors, frame, plane


# ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Spec:
    description: str
    params: dict[str, Param]
    builder: Callable
    duration: float
    targets: int


SCENARIO_SPECS: dict[str, _Spec] = {
    "thesis-stt": _Spec(
        "one CV target, 50 scans, P_D 0.6, two clutter regions ([thesis] §7.3)",
        _STT_PARAMS, _build_stt, 50.0, 1,
    ),
    "thesis-mtt-5": _Spec(
        "5 targets radially inward, crossing at scan 20, 40 scans ([thesis] §7.4)",
        _mtt_params(10.0), _build_mtt, 40.0, 5,
    ),
    "thesis-mtt-15": _Spec(
        "15 targets radially inward, crossing at scan 20, 40 scans ([thesis] §7.4)",
        _mtt_params(10.0), _build_mtt, 40.0, 15,
    ),
    "thesis-mtt-50": _Spec(
        "50 targets radially inward (7° apart), crossing at scan 20, 40 scans ([thesis] §7.4)",
        _mtt_params(7.0), _build_mtt, 40.0, 50,
    ),
    "lm-ipf-2": _Spec(
        "2 targets 20° apart from r = 450 m through c + δ at scan 20 ([LM-IPF])",
        _lmipf_params(20.0), _build_lmipf, 40.0, 2,
    ),
    "lm-ipf-15": _Spec(
        "15 targets 10° apart from r = 450 m through c + δ at scan 20 ([LM-IPF])",
        _lmipf_params(10.0), _build_lmipf, 40.0, 15,
    ),
    "crossing-4g": _Spec(
        "one radar, two targets at 50 km in opposite 4 g turns that cross ([MZD] §2, §4)",
        {**_CROSS_PARAMS, **bias_parameters(["radar"])}, _build_crossing, 72.0, 2,
    ),
    "regional": _Spec(
        "4 real radar sites (Belgrade, Vršac, Timișoara, Novi Sad; up to 6 with Osijek, "
        "Szeged), mixed 2d/3d, air traffic",
        {**_REGIONAL_PARAMS, **REPORT_PARAMETERS,
         **bias_parameters([r.radar_id for r in _REGIONAL_RADARS])},
        _build_regional, 300.0, 40,
    ),
}  # fmt: skip

SCENARIOS: dict[str, str] = {name: spec.description for name, spec in SCENARIO_SPECS.items()}
"""Scenario name → short description."""


def scenario_parameters(name: str) -> dict[str, Param]:
    """All parameters of a scenario (besides seed, duration and targets) with defaults."""
    spec = _spec(name)
    return {**_COMMON, **spec.params}


def _spec(name: str) -> _Spec:
    if name not in SCENARIO_SPECS:
        raise ValueError(f"unknown scenario {name!r}; valid scenarios: {', '.join(SCENARIOS)}")
    return SCENARIO_SPECS[name]


def build_scenario(
    name: str,
    *,
    seed: int = 1,
    duration: float | None = None,
    targets: int | None = None,
    **params,
) -> Scenario:
    """Build a named scenario. ``seed`` seeds the trajectories (and is the default
    measurement seed of :class:`~fusion.sim.Simulator`); ``duration`` (s) and
    ``targets`` override the defaults; other keyword arguments set scenario parameters
    (see :func:`scenario_parameters`). Unknown names or bad values raise ``ValueError``
    naming them and the valid choices."""
    spec = _spec(name)
    allowed = scenario_parameters(name)
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        raise ValueError(
            f"scenario {name!r}: unknown parameter {unknown[0]!r}; valid parameters: "
            f"seed, duration, targets, {', '.join(allowed)}"
        )
    seed = coerce(name, "seed", seed, Param(0, "", non_negative))
    dur = coerce(name, "duration", spec.duration if duration is None else duration,
                 Param(0.0, "", in_range(1e-3, 1e6)))  # fmt: skip
    n = coerce(name, "targets", spec.targets if targets is None else targets,
               Param(0, "", in_range(1, 10_000)))  # fmt: skip
    values = {k: coerce(name, k, params.get(k, prm.default), prm) for k, prm in allowed.items()}
    tgt, sensors, frame, plane = spec.builder(values, seed, dur, n)
    sensors = apply_site_biases(sensors, values)
    truth_period = values["truth_period"] or sensors[0].site.scan_period
    values["truth_period"] = truth_period
    record = {"seed": seed, "duration": dur, "targets": n, **values}
    return Scenario(
        name=name,
        description=spec.description,
        sites=[s.site for s in sensors],
        frame=frame,
        duration=dur,
        start_time=values["start_time"],
        n_targets=len(tgt),
        params=record,
        targets=tgt,
        sensors=sensors,
        plane=plane,
        truth_period=truth_period,
        seed=seed,
    )
