"""skyfuse vs Stone Soup 1.9.1 on the same simulated plots: ms per scan and GOSPA.

Both trackers consume the SAME plots, generated once by skyfuse's simulator
(:class:`fusion.sim.Simulator` over a :class:`fusion.sim.Scenario` built here):

* ``cartesian``: N targets flying straight (50-250 m/s, random headings) in a 200 km ×
  200 km plane, one cartesian sensor (σ = 25 m per axis, P_D = 0.9, T = 1 s) with uniform
  Poisson clutter (``--clutter`` plots per scan);
* ``crossing``: association matters. Pairs of targets (100-200 m/s) whose straight paths
  cross at mid-run at 20-60°, passing within 0-150 m of each other, in a 20 km × 20 km
  plane seen by the cartesian sensor. The same ``--clutter`` plots per scan fall on an
  area 100× smaller, i.e. 100× the clutter density of ``cartesian``;
* ``manoeuvring``: the motion model matters. Targets at 150-250 m/s in a 60 km × 60 km
  plane seen by the cartesian sensor; each flies straight 8-15 s, turns by 60-120° at
  2-3 g, flies straight 8-15 s, turns back by 60-120° at 2-3 g and flies straight to the
  end. skyfuse runs its IMM (``motion = imm-cv-ct``, the service default) and, as a
  reference, CV; Stone Soup 1.9.1 has no IMM, so it runs its best comparable model, a
  Singer KF (``Singer`` per axis, τ = ``--ss-singer-tau``, σ_m = ``--ss-singer-sigma-m``:
  q = 2σ_m²/τ);
* ``polar``: the same kind of traffic seen by one rotating 2d radar at the plane origin
  (σ_r = 30 m, σ_θ = 1.5 mrad, P_D = 0.9, T = 4 s, 150 km) with uniform clutter over its
  disc; every plot carries its own beam-crossing time.

skyfuse runs ``gnn`` (single Kalman filter per track), ``jipda`` and ``lmits`` (N = 3)
through :class:`fusion.tracker.TrackPipeline` (plot conversion into the system frame
included in the time). Stone Soup runs ``GNNWith2DAssignment`` with a Kalman filter
(cartesian) or an extended Kalman filter with ``CartesianToBearingRange`` (polar), and
``JPDA`` + Kalman with ``MultiTargetMixtureTracker`` (cartesian). Stone Soup's settings
(the "fair setting", documented in docs/performance.md):

* the same constant-velocity model with the same velocity process noise per scan (Stone
  Soup's continuous ``ConstantVelocity(q)``, skyfuse's discrete q/T), the same measurement
  noise;
* gates at the same probability P_G = 0.99 (GNN: Mahalanobis ``missed_distance`` =
  √χ²₂(0.99) = 3.03; JPDA: ``prob_gate`` 0.99, ``prob_detect`` 0.9 and the true clutter
  density);
* ``MultiMeasurementInitiator`` (GNN-associated holding tracks from unassociated plots,
  confirmed after ``min_points`` = 3 plots, i.e. two-point initiation + one confirming
  update like skyfuse's), holding tracks deleted after 2 scans without a plot;
* ``UpdateTimeStepsDeleter``: a track is deleted after 3 scans without a plot.

Timing: each (scenario, pairing) is run ``--repeats`` times, alternating skyfuse and
Stone Soup (the order swaps every repetition) in one process; tracker construction,
plot preparation (PlotBatch / Detection objects) and the loading of skyfuse's compiled
kernels (``kernel_warmup``, as the fusion service does at start) are outside the timed
region; the
medians over repetitions of the mean ms per scan are reported, in wall time
(``ms_per_scan``, ``speedup``) and in CPU time of the process (``time.process_time``:
``cpu_ms_per_scan``, ``speedup_cpu``; on a shared, loaded machine the wall time of
skyfuse's millisecond steps includes other jobs' time slices, the CPU time does not).
GOSPA (p = 1, α = 2, cut-off c) of every scan is computed by ONE implementation, Stone
Soup's ``GOSPAMetric``, between the truth at the scan end and each system's output tracks
(skyfuse: confirmed tracks; Stone Soup: its tracks, which its initiator releases only
once confirmed), both predicted to the scan end.

    python benchmarks/compare_stonesoup.py                       # 10 and 50 targets, 30 scans
    python benchmarks/compare_stonesoup.py --targets 50 --scans 100 --json h.json
    python benchmarks/compare_stonesoup.py --targets 10 50 200 --repeats 3   # full, long

Needs ``pip install .[bench]`` (stonesoup==1.9.1).
"""

from __future__ import annotations

import argparse
import datetime as dt
import gc
import json
import math
import os
import platform
import statistics
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from skyfuse.fusion.frames import Stereographic  # noqa: E402
from skyfuse.fusion.sim import Simulator  # noqa: E402
from skyfuse.fusion.sim.scenario import DEFAULT_START_TIME, Scenario  # noqa: E402
from skyfuse.fusion.sim.sensor import SensorConfig  # noqa: E402
from skyfuse.fusion.sim.trajectories import TargetSet, TrajectoryBuilder  # noqa: E402
from skyfuse.fusion.tracker import TrackerConfig  # noqa: E402
from skyfuse.schemas import FrameKind, FrameSpec, RadarSite  # noqa: E402
from skyfuse.services.fusion.pipeline import TrackPipeline  # noqa: E402

LAT0, LON0 = 44.8, 20.45
GATE_P = 0.99
GATE_D = math.sqrt(-2.0 * math.log(1.0 - GATE_P))  # √χ²₂(0.99) = 3.035
EPOCH = dt.datetime(2026, 1, 1, tzinfo=dt.UTC)


# ----------------------------------------------------------------------------- scenarios
@dataclass
class Setup:
    """One benchmark scenario: the skyfuse scenario plus the constants both sides use."""

    kind: str  # plots: cartesian | polar
    n_targets: int
    clutter: float  # mean false plots per scan
    scans: int
    period: float
    sigma: tuple[float, ...]  # cartesian: (σ,); polar: (σ_r, σ_θ)
    p_detection: float
    q: float
    gospa_c: float
    scenario: Scenario = field(repr=False)
    case: str = ""  # the benchmark case: cartesian | crossing | manoeuvring | polar
    ss_singer: tuple[float, float] = (10.0, 20.0)  # manoeuvring: Stone Soup's (τ s, σ_m m/s²)

    def __post_init__(self) -> None:
        self.case = self.case or self.kind


def _traffic(rng: np.random.Generator, n: int, centre: float, half: float, duration: float):
    """n straight-flying targets starting in the square centre ± half (m), 50-250 m/s."""
    pos = rng.uniform(centre - half, centre + half, (n, 2))
    speed = rng.uniform(50.0, 250.0, n)
    head = rng.uniform(0.0, 2.0 * np.pi, n)
    vel = speed[:, None] * np.column_stack([np.sin(head), np.cos(head)])
    builders = []
    for p, v in zip(pos, vel):
        b = TrajectoryBuilder(0.0, (p[0], p[1], 0.0), (v[0], v[1], 0.0))
        b.straight(duration + 1.0)
        builders.append(b)
    return TargetSet.from_builders(builders)


def _crossing_traffic(rng: np.random.Generator, n: int, side: float, duration: float):
    """n targets in pairs whose straight paths cross at t = duration/2 at 20-60°, with a
    miss distance of 0-150 m, crossing points in the central half of the square."""
    builders = []
    t_mid = duration / 2
    for i in range(n):
        if i % 2 == 0:
            centre = rng.uniform(0.25 * side, 0.75 * side, 2)
            head = rng.uniform(0.0, 2.0 * np.pi)
            offset = rng.uniform(0.0, 150.0) * np.array([np.cos(head), -np.sin(head)])
        else:
            head += rng.uniform(np.radians(20), np.radians(60)) * rng.choice([-1, 1])
            centre = centre + offset
        v = rng.uniform(100.0, 200.0) * np.array([np.sin(head), np.cos(head)])
        p = centre - v * t_mid
        b = TrajectoryBuilder(0.0, (p[0], p[1], 0.0), (v[0], v[1], 0.0))
        b.straight(duration + 1.0)
        builders.append(b)
    return TargetSet.from_builders(builders)


def _manoeuvring_traffic(rng: np.random.Generator, n: int, side: float, duration: float):
    """n targets (150-250 m/s, random headings, starting in the central fifth of the
    square): straight 8-15 s, a 60-120° turn at 2-3 g, straight 8-15 s, a 60-120° turn the
    other way at 2-3 g, straight to the end (the civil-aircraft turns the IMM defaults are
    tuned for)."""
    builders = []
    for _ in range(n):
        p = rng.uniform(0.4 * side, 0.6 * side, 2)
        head = rng.uniform(0.0, 2.0 * np.pi)
        v = rng.uniform(150.0, 250.0) * np.array([np.sin(head), np.cos(head)])
        b = TrajectoryBuilder(0.0, (p[0], p[1], 0.0), (v[0], v[1], 0.0))
        sign = rng.choice([-1.0, 1.0])
        for turn in (sign, -sign):
            b.straight(rng.uniform(8.0, 15.0))
            b.turn_by(turn * np.radians(rng.uniform(60.0, 120.0)), rng.uniform(2.0, 3.0))
        b.straight(duration + 1.0)
        builders.append(b)
    return TargetSet.from_builders(builders)


def build_setup(kind: str, n_targets: int, clutter: float, scans: int, seed: int) -> Setup:
    """The cartesian, crossing, manoeuvring or polar benchmark scenario (see the module
    docstring)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(7, n_targets)))
    frame = FrameSpec(kind=FrameKind.PLANAR, lat0=LAT0, lon0=LON0)
    plane = Stereographic(LAT0, LON0)
    case = kind
    if kind in ("cartesian", "crossing", "manoeuvring"):
        period, sigma, q, c = 1.0, 25.0, 1.0, 250.0
        side = {"cartesian": 200_000.0, "crossing": 20_000.0, "manoeuvring": 60_000.0}[kind]
        duration = scans * period
        if kind == "cartesian":
            targets = _traffic(rng, n_targets, side / 2, 0.35 * side, duration)
        elif kind == "crossing":
            targets = _crossing_traffic(rng, n_targets, side, duration)
        else:
            targets = _manoeuvring_traffic(rng, n_targets, side, duration)
        kind = "cartesian"
        site = RadarSite(
            radar_id="sensor", name="cartesian sensor", lat=LAT0, lon=LON0, alt=0.0,
            kind="cartesian", sigma_cartesian=sigma, scan_period=period, p_detection=0.9,
            max_range=side * 1.5, clutter_density=clutter / side**2, n_sectors=1,
        )  # fmt: skip
        sensors = [SensorConfig(site=site, first_scan=1, coverage=(0.0, side, 0.0, side))]
        sig: tuple[float, ...] = (sigma,)
    elif kind == "polar":
        period, rmax, sr, sa, q, c = 4.0, 150_000.0, 30.0, 1.5e-3, 1.0, 1000.0
        duration = scans * period
        # start within 25-90 km of the radar so most stay in cover for the whole run
        r0 = np.sqrt(rng.uniform(25e3**2, 90e3**2, n_targets))
        a0 = rng.uniform(0, 2 * np.pi, n_targets)
        pos = np.column_stack([r0 * np.sin(a0), r0 * np.cos(a0)])
        speed = rng.uniform(50.0, 250.0, n_targets)
        head = rng.uniform(0.0, 2.0 * np.pi, n_targets)
        vel = speed[:, None] * np.column_stack([np.sin(head), np.cos(head)])
        builders = []
        for p, v in zip(pos, vel):
            b = TrajectoryBuilder(0.0, (p[0], p[1], 0.0), (v[0], v[1], 0.0))
            b.straight(duration + period + 1.0)
            builders.append(b)
        targets = TargetSet.from_builders(builders)
        site = RadarSite(
            radar_id="radar", name="2d radar", lat=LAT0, lon=LON0, alt=0.0, kind="2d",
            sigma_range=sr, sigma_azimuth=sa, sigma_altitude=10.0, scan_period=period,
            p_detection=0.9, max_range=rmax, clutter_density=clutter / (np.pi * rmax**2),
            n_sectors=1,
        )  # fmt: skip
        sensors = [SensorConfig(site=site, phase=0.0, clutter_max_altitude=0.0)]
        sig = (sr, sa)
    else:
        raise ValueError(
            f"kind = {kind!r}: must be 'cartesian', 'crossing', 'manoeuvring' or 'polar'"
        )
    scenario = Scenario(
        name=f"bench-{case}", description=f"{n_targets} {case} targets, {kind} plots",
        sites=[site], frame=frame, duration=duration, start_time=DEFAULT_START_TIME,
        n_targets=n_targets, params={"targets": n_targets, "clutter": clutter},
        targets=targets, sensors=sensors, plane=plane, truth_period=period, seed=seed,
    )  # fmt: skip
    return Setup(kind, n_targets, clutter, scans, period, sig, 0.9, q, c, scenario, case)


# ------------------------------------------------------------------------ shared plots
@dataclass
class ScanInput:
    time_ns: int
    batch: object  # PlotBatch
    detections: set  # Stone Soup Detections
    truth: np.ndarray  # (n, 4) [x, vx, y, vy] at time_ns, targets alive and in cover


def _ss_time(t_ns: int) -> dt.datetime:
    return EPOCH + dt.timedelta(microseconds=(int(t_ns) - DEFAULT_START_TIME) / 1000.0)


def prepare(setup: Setup, ss: dict, time_bin: float = 0.0) -> list[ScanInput]:
    """Simulate once; build skyfuse PlotBatches and Stone Soup Detections of every scan.

    ``time_bin`` (s, > 0): Stone Soup detections carry their plot time rounded to this
    step (Stone Soup caches one prediction per track and timestamp, so exact plot times
    cost one prediction per track-plot pair; skyfuse always uses exact times)."""
    from stonesoup.types.angle import Bearing
    from stonesoup.types.array import StateVector
    from stonesoup.types.detection import Detection

    sc = setup.scenario
    sim = Simulator(sc, seed=sc.seed)
    out = []
    mm = ss["measurement_model"]
    rmax = sc.sites[0].max_range
    for k, scan in enumerate(sim.scans()):
        if k >= setup.scans:
            break
        (batch,) = Simulator.sector_batches(scan, k)
        times = scan.time
        if time_bin > 0:
            step = round(time_bin * 1e9)
            k_bin = np.round((times - scan.time_start) / step).astype(np.int64)
            times = scan.time_start + k_bin * step
        if setup.kind == "cartesian":
            zs = [StateVector([x, y]) for x, y in zip(scan.x, scan.y)]
        else:
            bearing = np.pi / 2 - scan.azimuth  # clockwise from north → ccw from x (east)
            zs = [StateVector([Bearing(b), r]) for b, r in zip(bearing, scan.range)]
        dets = {
            Detection(z, timestamp=_ss_time(t), measurement_model=mm)
            for z, t in zip(zs, times.tolist())
        }
        t_end = int(scan.time_end)
        ts = (t_end - sc.start_time) * 1e-9
        pos, vel = sc.targets.state(ts)
        alive = sc.targets.alive(ts)
        if setup.kind == "polar":
            alive &= np.hypot(pos[:, 0], pos[:, 1]) <= rmax
        truth = np.column_stack([pos[:, 0], vel[:, 0], pos[:, 1], vel[:, 1]])[alive]
        out.append(ScanInput(t_end, batch, dets, truth))
    return out


# ------------------------------------------------------------------------------ skyfuse
def skyfuse_config(setup: Setup, kind: str) -> TrackerConfig:
    """skyfuse settings: the defaults, with the benchmark's noise and scan period;
    ``kind`` is a tracker kind or ``KIND:MOTION`` (default motion here: cv).

    skyfuse's CV model is the discrete white-noise acceleration one, Q = q [[T⁴/4, T³/2],
    [T³/2, T²]]; Stone Soup's the continuous one, Q = q [[T³/3, T²/2], [T²/2, T]]. skyfuse
    gets q/T so that both have the same velocity variance per scan (identical at T = 1 s;
    at T = 4 s the same q would give skyfuse 4× Stone Soup's process noise)."""
    tracker, _, motion = kind.partition(":")
    return TrackerConfig(
        tracker=tracker,
        motion=motion or "cv",
        depth=3,
        q=setup.q / setup.period,
        p_gate=GATE_P,
        v_max=300.0,
        # the plot buffer expires from the batch END, so with a rotating radar a plot can
        # wait up to 2 T for its partner in the next revolution
        init_max_dt=2.5 * setup.period,
        init_min_dt=0.5 * setup.period,
        clutter="known",
    )


def run_skyfuse(
    setup: Setup, scans: list[ScanInput], kind: str
) -> tuple[list[float], list[float], list]:
    """Per-scan wall ms, per-scan CPU ms of this process and per-scan (n, 4) confirmed
    track states at the scan end."""
    pipe = TrackPipeline(setup.scenario.frame, skyfuse_config(setup, kind))
    site = setup.scenario.sites[0]
    ms, cpu, est = [], [], []
    for s in scans:
        t0, c0 = time.perf_counter(), time.process_time()
        out = pipe.step(site, s.batch)
        ms.append((time.perf_counter() - t0) * 1e3)
        cpu.append((time.process_time() - c0) * 1e3)
        est.append(out.states[out.confirmed])
    return ms, cpu, est


# ---------------------------------------------------------------------------- Stone Soup
def stonesoup_models(setup: Setup) -> dict:
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.measurement.nonlinear import CartesianToBearingRange
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        ConstantVelocity,
    )

    if setup.case == "manoeuvring":
        return _stonesoup_singer_models(setup)
    trans = CombinedLinearGaussianTransitionModel(
        [ConstantVelocity(setup.q), ConstantVelocity(setup.q)]
    )
    if setup.kind == "cartesian":
        s = setup.sigma[0]
        mm = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.diag([s**2, s**2]))
    else:
        sr, sa = setup.sigma
        mm = CartesianToBearingRange(
            ndim_state=4, mapping=(0, 2), noise_covar=np.diag([sa**2, sr**2])
        )
    return {
        "transition_model": trans,
        "measurement_model": mm,
        "state_index": (0, 1, 2, 3),
        "prior_var": (1e8, 150.0**2, 1e8, 150.0**2),
    }


def _stonesoup_singer_models(setup: Setup) -> dict:
    """Stone Soup's Singer KF per axis, state [x, vx, ax, y, vy, ay]: damping 1/τ and
    noise diffusion q = 2σ_m²/τ, so that the stationary acceleration variance q/(2/τ) is
    σ_m² (Singer 1970)."""
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, Singer

    tau, sigma_m = setup.ss_singer
    axis = Singer(noise_diff_coeff=2.0 * sigma_m**2 / tau, damping_coeff=1.0 / tau)
    s = setup.sigma[0]
    return {
        "transition_model": CombinedLinearGaussianTransitionModel([axis, axis]),
        "measurement_model": LinearGaussian(
            ndim_state=6, mapping=(0, 3), noise_covar=np.diag([s**2, s**2])
        ),
        "state_index": (0, 1, 3, 4),
        "prior_var": (1e8, 150.0**2, sigma_m**2, 1e8, 150.0**2, sigma_m**2),
    }


class _Detections:
    """A Stone Soup detector over prepared (time, detections) pairs."""

    def __init__(self, scans: list[ScanInput]) -> None:
        self.items = [(_ss_time(s.time_ns), s.detections) for s in scans]

    def __iter__(self):
        return iter(self.items)


def stonesoup_tracker(setup: Setup, ss: dict, kind: str, scans: list[ScanInput]):
    """Stone Soup's GNN (KF or EKF) or JPDA tracker in the documented fair setting."""
    from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
    from stonesoup.dataassociator.probability import JPDAwithEHM
    from stonesoup.deleter.time import UpdateTimeStepsDeleter
    from stonesoup.hypothesiser.distance import DistanceHypothesiser
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.initiator.simple import MultiMeasurementInitiator
    from stonesoup.measures import Mahalanobis
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.tracker.simple import MultiTargetMixtureTracker, MultiTargetTracker
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import ExtendedKalmanUpdater, KalmanUpdater

    mm = ss["measurement_model"]
    predictor = KalmanPredictor(ss["transition_model"])
    updater = (KalmanUpdater if setup.kind == "cartesian" else ExtendedKalmanUpdater)(mm)
    # prior: position from the first plot (large variance so the plot takes over),
    # speed unknown up to ~300 m/s
    prior_var = ss["prior_var"]
    prior = GaussianState(np.zeros((len(prior_var), 1)), np.diag(prior_var))
    init_hyp = DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=GATE_D)
    initiator = MultiMeasurementInitiator(
        prior_state=prior,
        deleter=UpdateTimeStepsDeleter(time_steps_since_update=2),
        data_associator=GNNWith2DAssignment(init_hyp),
        updater=updater,
        measurement_model=mm,
        min_points=3,
    )
    deleter = UpdateTimeStepsDeleter(time_steps_since_update=3)
    detector = _Detections(scans)
    if kind == "gnn":
        hyp = DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=GATE_D)
        return MultiTargetTracker(
            initiator=initiator,
            deleter=deleter,
            detector=detector,
            data_associator=GNNWith2DAssignment(hyp),
            updater=updater,
        )
    if kind == "jpda":
        area = setup.scenario.sensors[0].coverage
        density = setup.clutter / ((area[1] - area[0]) * (area[3] - area[2]))
        hyp = PDAHypothesiser(
            predictor,
            updater,
            clutter_spatial_density=max(density, 1e-12),
            prob_detect=setup.p_detection,
            prob_gate=GATE_P,
        )
        return MultiTargetMixtureTracker(
            initiator=initiator,
            deleter=deleter,
            detector=detector,
            data_associator=JPDAwithEHM(hyp),
            updater=updater,
        )
    raise ValueError(kind)


def run_stonesoup(
    setup: Setup, ss: dict, scans: list[ScanInput], kind: str
) -> tuple[list[float], list[float], list]:
    """Per-scan wall ms, per-scan CPU ms and per-scan (n, 4) track states predicted to
    the scan end."""
    tracker = stonesoup_tracker(setup, ss, kind, scans)
    F = ss["transition_model"]
    index = list(ss["state_index"])  # → [x, vx, y, vy]
    it = iter(tracker)
    ms, cpu, est = [], [], []
    for s in scans:
        t0, c0 = time.perf_counter(), time.process_time()
        _, tracks = next(it)
        ms.append((time.perf_counter() - t0) * 1e3)
        cpu.append((time.process_time() - c0) * 1e3)
        t_end = _ss_time(s.time_ns)
        rows = []
        for tr in tracks:
            st = tr.state
            lag = (t_end - st.timestamp).total_seconds()
            x = np.asarray(st.state_vector, dtype=float).ravel()
            x = F.matrix(time_interval=dt.timedelta(seconds=lag)) @ x if lag else x
            rows.append(x[index])
        est.append(np.array(rows).reshape(-1, 4))
    return ms, cpu, est


# -------------------------------------------------------------------------------- GOSPA
def gospa_series(setup: Setup, scans: list[ScanInput], est: list) -> dict:
    """Mean GOSPA (p = 1, α = 2, c = setup.gospa_c) and its parts over the scans after
    the first ``warm`` (track initiation), all computed by Stone Soup's GOSPAMetric;
    polar: truth and tracks inside the radar's range only."""
    from stonesoup.measures import Euclidean
    from stonesoup.metricgenerator.ospametric import GOSPAMetric
    from stonesoup.types.state import State

    metric = GOSPAMetric(c=setup.gospa_c, p=1, measure=Euclidean(mapping=(0, 2)))
    warm = 5
    parts = {"distance": [], "localisation": [], "missed": [], "false": []}
    rmax = setup.scenario.sites[0].max_range
    for s, e in list(zip(scans, est))[warm:]:
        t = _ss_time(s.time_ns)
        if setup.kind == "polar":
            # evaluate inside the radar's cover only, for truth (see prepare) and tracks
            # alike: skyfuse keeps a track that left every radar's cover without eroding
            # it (no radar saw that region), Stone Soup deletes it after 3 scans
            e = e[np.hypot(e[:, 0], e[:, 2]) <= rmax]
        meas = [State(row.reshape(4, 1), timestamp=t) for row in e]
        truth = [State(row.reshape(4, 1), timestamp=t) for row in s.truth]
        if not meas and not truth:
            for v in parts.values():
                v.append(0.0)
            continue
        g, _ = metric.compute_gospa_metric(meas, truth)
        for key in parts:
            parts[key].append(float(g.value[key]))
    res = {f"gospa_{k}": round(float(np.mean(v)), 2) for k, v in parts.items()}
    res["gospa_scans"] = len(parts["distance"])
    res["tracks_mean"] = round(float(np.mean([len(e) for e in est[warm:]])), 1)
    return res


# --------------------------------------------------------------------------------- main
PAIRINGS = {
    # (scenario kind, skyfuse tracker, Stone Soup tracker, label)
    "cartesian": [("gnn", "gnn", "GNN + KF"), ("jipda", "jpda", "JIPDA vs JPDA + KF"),
                  ("lmits", "jpda", "LM-ITS N=3 vs JPDA + KF")],
    "crossing": [("gnn", "gnn", "GNN + KF"), ("jipda", "jpda", "JIPDA vs JPDA + KF"),
                 ("lmits", "jpda", "LM-ITS N=3 vs JPDA + KF")],
    "manoeuvring": [("gnn:imm-cv-ct", "gnn", "IMM-GNN vs GNN + Singer KF"),
                    ("jipda:imm-cv-ct", "jpda", "IMM-JIPDA vs JPDA + Singer KF"),
                    ("lmits:imm-cv-ct", "jpda", "IMM-LM-ITS N=3 vs JPDA + Singer KF"),
                    ("jipda:imm-cv-singer", "jpda", "IMM-JIPDA (CV+Singer) vs JPDA + Singer KF"),
                    ("lmits", "jpda", "LM-ITS N=3 CV vs JPDA + Singer KF")],
    "polar": [("gnn", "gnn", "GNN + EKF (polar)"), ("jipda", "gnn", "JIPDA vs GNN + EKF"),
              ("lmits", "gnn", "LM-ITS N=3 vs GNN + EKF")],
}  # fmt: skip


def _case_row(setup: Setup, plots: float, scans: list[ScanInput], label: str, sf, ss) -> dict:
    """One result row: ``sf`` / ``ss`` = (tracker, wall ms per run, CPU ms per run,
    estimates); speed-ups from the medians over runs, of wall time and of CPU time."""
    sides = {}
    for name, (kind, ms, cpu, est) in (("skyfuse", sf), ("stonesoup", ss)):
        sides[name] = {"tracker": kind, "ms_per_scan": round(statistics.median(ms), 3),
                       "ms_per_scan_runs": [round(v, 3) for v in ms],
                       "cpu_ms_per_scan": round(statistics.median(cpu), 3),
                       "cpu_ms_per_scan_runs": [round(v, 3) for v in cpu],
                       **gospa_series(setup, scans, est)}  # fmt: skip
    sfs, sss = sides["skyfuse"], sides["stonesoup"]
    return {
        "scenario": setup.case,
        "targets": setup.n_targets,
        "clutter_per_scan": setup.clutter,
        "plots_per_scan": round(plots, 1),
        "scans": len(scans),
        "pairing": label,
        **sides,
        "speedup": round(sss["ms_per_scan"] / sfs["ms_per_scan"], 1),
        "speedup_cpu": round(sss["cpu_ms_per_scan"] / sfs["cpu_ms_per_scan"], 1),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }


def bench_case(
    setup: Setup, repeats: int, ss_repeats: int, log, time_bin: float = 0.0
) -> list[dict]:
    ss = stonesoup_models(setup)
    t0 = time.perf_counter()
    scans = prepare(setup, ss, time_bin if setup.kind == "polar" else 0.0)
    plots = float(np.mean([len(s.detections) for s in scans]))
    log(
        f"  {setup.case} {setup.n_targets} targets, {setup.clutter:g} clutter/scan: "
        f"{len(scans)} scans, {plots:.0f} plots/scan (prepared in {time.perf_counter() - t0:.1f} s)"
    )
    ss_cache: dict[str, tuple[list[float], list[float], list]] = {}
    rows = []
    for sf_kind, ss_kind, label in PAIRINGS[setup.case]:
        sf_ms, ss_ms, sf_cpu, ss_cpu = [], [], [], []
        sf_est = ss_est = None
        n_ss = 0 if ss_kind in ss_cache and ss_repeats <= len(ss_cache[ss_kind][0]) else ss_repeats
        for r in range(max(repeats, n_ss)):
            order = ("sf", "ss") if r % 2 == 0 else ("ss", "sf")
            for who in order:
                gc.collect()  # neither side pays for the other's garbage
                if who == "sf" and r < repeats:
                    ms, cpu, sf_est = run_skyfuse(setup, scans, sf_kind)
                    sf_ms.append(float(np.mean(ms)))
                    sf_cpu.append(float(np.mean(cpu)))
                elif who == "ss" and r < n_ss:
                    ms, cpu, est = run_stonesoup(setup, ss, scans, ss_kind)
                    ss_ms.append(float(np.mean(ms)))
                    ss_cpu.append(float(np.mean(cpu)))
                    ss_est = est
        if n_ss == 0:
            ss_ms, ss_cpu, ss_est = ss_cache[ss_kind]
        else:
            ss_cache[ss_kind] = (ss_ms, ss_cpu, ss_est)
        row = _case_row(setup, plots, scans, label, (sf_kind, sf_ms, sf_cpu, sf_est),
                        (ss_kind, ss_ms, ss_cpu, ss_est))  # fmt: skip
        rows.append(row)
        sf, st = row["skyfuse"], row["stonesoup"]
        log(
            f"    {label:<26} skyfuse {sf_kind:>5} {sf['ms_per_scan']:8.2f} ms "
            f"(CPU {sf['cpu_ms_per_scan']:.2f})  GOSPA {sf['gospa_distance']:9.1f} | Stone Soup "
            f"{ss_kind:>4} {st['ms_per_scan']:9.1f} ms (CPU {st['cpu_ms_per_scan']:.1f})  GOSPA "
            f"{st['gospa_distance']:9.1f} | ×{row['speedup']:.0f} (CPU ×{row['speedup_cpu']:.0f})"
        )
    return rows


def markdown_table(paths: list[Path]) -> str:
    """Markdown table of the cases in result files (for docs/performance.md)."""
    lines = [
        "| kind | targets | plots/scan | skyfuse | Stone Soup | skyfuse ms/scan "
        "| Stone Soup ms/scan | speed-up | speed-up (CPU) | GOSPA skyfuse (loc/miss/false) "
        "| GOSPA Stone Soup (loc/miss/false) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]

    def g(side: dict) -> str:
        return (
            f"{side['gospa_distance']:.0f} ({side['gospa_localisation']:.0f}/"
            f"{side['gospa_missed']:.0f}/{side['gospa_false']:.0f})"
        )

    def cpu_speedup(c: dict) -> str:
        return f"×{c['speedup_cpu']:.0f}" if "speedup_cpu" in c else "–"

    names = {"gnn": "GNN", "jipda": "JIPDA", "lmits": "LM-ITS N=3", "jpda": "JPDA (EHM)"}
    for path in paths:
        for c in json.loads(Path(path).read_text())["cases"]:
            sf, ss = c["skyfuse"], c["stonesoup"]
            model = {"polar": " EKF", "manoeuvring": " Singer KF"}.get(c["scenario"], " KF")
            ss_name = names[ss["tracker"]] + model
            sf_kind, _, motion = sf["tracker"].partition(":")
            lines.append(
                f"| {c['scenario']} | {c['targets']} | {c['plots_per_scan']:.0f} "
                f"| {names[sf_kind]}{' ' + motion if motion else ''} | {ss_name} "
                f"| {sf['ms_per_scan']:.1f} "
                f"| {ss['ms_per_scan']:.0f} | ×{c['speedup']:.0f} "
                f"| {cpu_speedup(c)} | {g(sf)} | {g(ss)} |"
            )
    return "\n".join(lines)


def machine() -> dict:
    import scipy
    import stonesoup

    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "stonesoup": stonesoup.__version__,
        "platform": platform.platform(),
        "load_average_1_5_15_min": [round(v, 2) for v in os.getloadavg()],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--targets", type=int, nargs="+", default=[10, 50], help="target counts")
    ap.add_argument("--scans", type=int, default=30, help="scans per run")
    ap.add_argument(
        "--clutter",
        type=float,
        default=20.0,
        help="mean false plots per scan over the whole coverage (default 20)",
    )
    ap.add_argument(
        "--ss-time-bin",
        type=float,
        default=0.0,
        help="polar: Stone Soup detection times rounded to this step, s (default 0: exact "
        "plot times; 0.25 makes Stone Soup ~1.7x faster and slightly less accurate; "
        "skyfuse always uses exact times)",
    )
    ap.add_argument(
        "--scenarios",
        nargs="+",
        default=["cartesian", "polar"],
        choices=["cartesian", "crossing", "manoeuvring", "polar"],
    )
    ap.add_argument(
        "--ss-singer-tau", type=float, default=10.0, help="manoeuvring: Stone Soup Singer τ, s"
    )
    ap.add_argument(
        "--ss-singer-sigma-m",
        type=float,
        default=20.0,
        help="manoeuvring: Stone Soup Singer σ_m, m/s² (default 20)",
    )
    ap.add_argument("--repeats", type=int, default=3, help="skyfuse repetitions (median)")
    ap.add_argument(
        "--ss-repeats",
        type=int,
        default=None,
        help="Stone Soup repetitions (default: --repeats, 1 when its run would be long)",
    )
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", type=Path, default=None, help="write the results here")
    ap.add_argument(
        "--report", type=Path, nargs="+", default=None, help="print a Markdown table of these"
    )
    args = ap.parse_args(argv)
    if args.report:
        print(markdown_table(args.report))
        return 0
    try:
        import stonesoup  # noqa: F401
    except ImportError:
        print("Stone Soup is not installed: pip install .[bench]", file=sys.stderr)
        return 2

    def log(msg: str) -> None:
        print(msg, flush=True)

    # skyfuse's compiled kernels loaded from their cache before any timing, as the fusion
    # service does at start (otherwise the first pairing's first run pays the loading)
    from skyfuse.fusion.tracker.kernel_warmup import warm_up

    log(
        f"skyfuse vs Stone Soup: {args.scans} scans, repeats {args.repeats} "
        f"(skyfuse kernels loaded in {warm_up():.2f} s)"
    )
    rows = []
    t_all = time.perf_counter()

    def write(rows: list[dict], done: bool) -> None:
        if not args.json:
            return
        res = {
            "benchmark": "compare_stonesoup",
            "complete": done,
            "command": " ".join(
                ["python", "benchmarks/compare_stonesoup.py", *(argv or sys.argv[1:])]
            ),
            "settings": {
                "scans": args.scans,
                "repeats": args.repeats,
                "gate_probability": GATE_P,
                "clutter_per_scan": args.clutter,
                "stonesoup_polar_time_bin_s": args.ss_time_bin,
                "manoeuvring": "skyfuse KIND:imm-cv-ct (TrackerConfig IMM defaults) and lmits "
                "cv; Stone Soup Singer KF per axis, tau = "
                f"{args.ss_singer_tau} s, sigma_m = {args.ss_singer_sigma_m} m/s^2",
                "process_noise": "Stone Soup ConstantVelocity(q = 1) per axis; skyfuse "
                "q = 1/T (same velocity variance per scan)",
                "gospa": "Stone Soup GOSPAMetric, p = 1, alpha = 2, c = 250 m (cartesian), "
                "1000 m (polar); mean over scans after the first 5",
                "stonesoup": "MultiMeasurementInitiator(min_points=3, holding deleter 2 "
                "scans), UpdateTimeStepsDeleter(3), Mahalanobis gate 3.035 (GNN), "
                "JPDAwithEHM + PDAHypothesiser P_D 0.9 P_G 0.99 true clutter density",
            },
            "machine": machine(),
            "wall_s": round(time.perf_counter() - t_all, 1),
            "cases": rows,
        }
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(res, indent=2) + "\n")
        if done:
            log(f"wrote {args.json}")

    for kind in args.scenarios:
        for n in args.targets:
            clutter = float(args.clutter)
            setup = build_setup(kind, n, clutter, args.scans, args.seed)
            setup.ss_singer = (args.ss_singer_tau, args.ss_singer_sigma_m)
            ss_rep = args.ss_repeats
            if ss_rep is None:
                # Stone Soup costs ≈20 ms per target per scan on cartesian plots and
                # ≈180 ms with the EKF on polar plots (this machine, loaded): repeat it
                # only while the repetitions stay under ~2 minutes
                per = 0.18 if kind == "polar" else 0.02
                ss_rep = args.repeats if per * n * args.scans * args.repeats <= 120 else 1
            rows += bench_case(setup, args.repeats, ss_rep, log, args.ss_time_bin)
            write(rows, done=False)  # after every case: a long run keeps what it measured
    write(rows, done=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
