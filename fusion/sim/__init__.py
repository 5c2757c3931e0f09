"""Seeded, deterministic scenario simulator.

>>> from fusion.sim import build_scenario, Simulator
>>> sc = build_scenario("thesis-mtt-5", seed=3)
>>> sim = Simulator(sc)
>>> for scan in sim.scans():          # NumPy fast path (Monte Carlo)
...     z, tid = scan.z, scan.target_id
>>> events = list(sim.run())          # wire messages: RadarSite, PlotBatch, Truth

Modules: ``trajectories`` (analytic segment trajectories), ``sensor`` (sensor config and
clutter regions), ``radar`` (rotating 2d/3d radar), ``cartesian`` (planar thesis
sensor), ``scan`` (per-scan arrays), ``scenario`` (Scenario, parameters),
``scenarios`` (the named scenarios), ``simulator`` (Simulator, SimEvent).
"""

from .scan import ScanData
from .scenario import DEFAULT_START_TIME, Param, Scenario
from .scenarios import SCENARIOS, build_scenario, scenario_parameters
from .sensor import AnnulusRegion, RectRegion, SensorConfig
from .simulator import SimEvent, Simulator
from .trajectories import G0, TargetSet, TrajectoryBuilder

__all__ = [
    "DEFAULT_START_TIME",
    "G0",
    "SCENARIOS",
    "AnnulusRegion",
    "Param",
    "RectRegion",
    "ScanData",
    "Scenario",
    "SensorConfig",
    "SimEvent",
    "Simulator",
    "TargetSet",
    "TrajectoryBuilder",
    "build_scenario",
    "scenario_parameters",
]
