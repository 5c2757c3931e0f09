"""Definition of a Monte Carlo tracker experiment on a planar thesis scenario ([thesis] ch. 7).

An :class:`Experiment` names a scenario (``thesis-stt``, ``thesis-mtt-5/15/50``,
``lm-ipf-2/15``), the tracker **variants** to compare (tracker kind and Singer depth N),
the number of runs and the seed, and the tracker settings shared by every variant. The
settings default to the source's ([thesis] §7.1-7.4):

* CV model with q = 0.75 m²/s⁴, R = σ² I from the scenario (25 m²), T = 1 s;
* Markov chain one, Δ11 = 0.98, Δ21 = 0; gate P_G = 0.99 (g = 9.21, [IMPL]);
* **non-parametric** (estimated) clutter density (2.35), as the thesis experiments, with
  V_k = max(gate of the track's S, π (v_max T)²) (``clutter_volume``; [A]:
  the gate alone cannot give the source's tables, see docs/reproduction.md);
* two-point initiation from plots of consecutive scans only (``init_max_dt`` 1.5 T) no
  track selected, with v_max = 50 m/s ([A]: not in the thesis, [IMPL]);
* confirmation at ψ ≥ 0.99 (single target) / 0.95 (multi-target); termination at
  ψ < 10⁻³ ([IMPL]); ψ_init per variant (calibrated, see ``calibration``).

Run r (0-based) uses seed ``run_seed(seed, r)`` = seed·100003 + r for both the scenario
(the thesis-mtt velocity randomisation) and the measurements, so every variant of a run
sees the same plots. Times of run r are shifted by r·duration so that, with false tracks
carried over ([thesis] §7.1), run r + 1's first scan is one scan period after
run r's last one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pydantic import BaseModel, ConfigDict, Field, field_validator
from skyfuse.fusion.tracker.config import SINGLE_GAUSSIAN_KINDS, TrackerConfig
from skyfuse.fusion.tracker.registry import TRACKERS

#: Scenarios with the planar cartesian sensor the fast Monte Carlo path supports.
PLANAR_SCENARIOS = (
    "thesis-stt",
    "thesis-mtt-5",
    "thesis-mtt-15",
    "thesis-mtt-50",
    "lm-ipf-2",
    "lm-ipf-15",
)

#: The source's target number of confirmed false tracks per experiment of 500 runs
#: ([thesis] §7.1): 20 single-target, 15 multi-target, each ± 10 %.
SOURCE_RUNS = 500
FALSE_TRACK_TARGET_STT = 20.0
FALSE_TRACK_TARGET_MTT = 15.0

#: Scan period of the planar scenarios, s ([thesis] §7.3-7.4).
SCAN_PERIOD = 1.0


def initiation_region(v_max: float, period: float = SCAN_PERIOD) -> float:
    """π (v_max T)², m²: the validation region of two-point initiation ([thesis] §7.1), the
    reading of the thesis's V_k in (2.35) that reproduces its tables (docs/reproduction.md)."""
    return math.pi * (v_max * period) ** 2


TRACKER_KINDS = tuple(TRACKERS)  # from the registry of fusion.tracker


def run_seed(seed: int, run: int) -> int:
    """Seed of Monte Carlo run ``run`` (scenario and measurements)."""
    return int(seed) * 100_003 + int(run)


@dataclass(frozen=True, order=True)
class Variant:
    """One tracker configuration of an experiment: kind and Singer depth N (0 for the
    single-Gaussian trackers ipda, lmipda, jipda, gnn)."""

    tracker: str
    depth: int

    @property
    def key(self) -> str:
        """Stable text key, e.g. ``lmits:7`` (used in JSON and cache names)."""
        return f"{self.tracker}:{self.depth}"

    @classmethod
    def from_key(cls, key: str) -> Variant:
        kind, _, depth = key.partition(":")
        if kind not in TRACKER_KINDS or not depth.isdigit():
            raise ValueError(f"variant key {key!r}: must be TRACKER:DEPTH, e.g. 'its:3'")
        return cls(kind, int(depth))


class Experiment(BaseModel):
    """A Monte Carlo experiment (see the module docstring)."""

    model_config = ConfigDict(extra="forbid")

    scenario: str = Field(description="Planar scenario: " + ", ".join(PLANAR_SCENARIOS))
    scenario_params: dict[str, float | int | str] = Field(
        default_factory=dict, description="Scenario parameters overriding its defaults"
    )
    trackers: list[str] = Field(["its", "lmits"], description="Tracker kinds")
    depths: list[int] = Field([1, 3, 5, 7, 9], description="Singer depths N")
    runs: int = Field(100, ge=1, le=100_000, description="Monte Carlo runs")
    seed: int = Field(1, ge=0, description="Seed; run r uses seed·100003 + r")
    psi_init: dict[str, float] = Field(
        default_factory=dict, description="ψ_init per variant key ('its:3'); else default"
    )
    default_psi_init: float = Field(0.01, gt=0, lt=0.9, description="ψ_init of other variants")
    carry_false_tracks: bool = Field(
        True, description="Carry false tracks into the next run ([thesis] §7.1)"
    )
    tracker_settings: dict[str, float | int | str] = Field(
        default_factory=dict,
        description="TrackerConfig fields overriding the source's settings (module docstring)",
    )
    k_start: int = Field(14, ge=1, description="Retention: scan at which cases are identified")
    k_end: int = Field(38, ge=2, description="Retention: scan at which cases are re-checked")
    gospa_c: float = Field(25.0, gt=0, description="GOSPA cut-off c, m")
    gospa_p: float = Field(2.0, ge=1, description="GOSPA order p")

    @field_validator("scenario")
    @classmethod
    def _planar(cls, v: str) -> str:
        if v not in PLANAR_SCENARIOS:
            raise ValueError(
                f"scenario {v!r}: the Monte Carlo tracker evaluation supports "
                f"{', '.join(PLANAR_SCENARIOS)} (for other scenarios record them with "
                "'skyfuse simulate' and use 'skyfuse eval FILE.mcap')"
            )
        return v

    @field_validator("trackers")
    @classmethod
    def _kinds(cls, v: list[str]) -> list[str]:
        if not v:
            raise ValueError("give at least one tracker")
        for k in v:
            if k not in TRACKER_KINDS:
                raise ValueError(
                    f"tracker {k!r} is not known; choose from {', '.join(TRACKER_KINDS)}"
                )
        return v

    @field_validator("depths")
    @classmethod
    def _depths(cls, v: list[int]) -> list[int]:
        if not v:
            raise ValueError("give at least one depth")
        for d in v:
            if not 0 <= d <= 12:
                raise ValueError(f"depth {d}: must be in 0..12")
        return v

    @property
    def single_target(self) -> bool:
        return self.scenario == "thesis-stt"

    @property
    def false_track_target(self) -> float:
        """The source's confirmed false tracks per 500 runs (20 STT, 15 MTT)."""
        return FALSE_TRACK_TARGET_STT if self.single_target else FALSE_TRACK_TARGET_MTT

    def variants(self) -> list[Variant]:
        """Tracker × depth, in the order given; single-Gaussian kinds once with N = 0."""
        out: list[Variant] = []
        for kind in self.trackers:
            depths = [0] if kind in SINGLE_GAUSSIAN_KINDS else self.depths
            for d in depths:
                v = Variant(kind, int(d))
                if v not in out:
                    out.append(v)
        return out

    def psi_for(self, variant: Variant) -> float:
        return float(self.psi_init.get(variant.key, self.default_psi_init))

    def tracker_config(self, variant: Variant, psi_init: float | None = None) -> TrackerConfig:
        """The TrackerConfig of ``variant`` (source settings, then ``tracker_settings``)."""
        base: dict[str, object] = {
            "tracker": variant.tracker,
            "depth": variant.depth,
            "motion": "cv",  # the source's constant-velocity model
            "q": 0.75,
            "p_gate": 0.99,
            "clutter": "estimated",
            "v_max": 50.0,
            "init_min_dt": 0.5,
            "init_max_dt": 1.5,
            "tau_confirm": 0.99 if self.single_target else 0.95,
            "tau_terminate": 1e-3,
            "delta11": 0.98,
            "delta21": 0.0,
            "existence_chain": "mc1",
        }
        base.update(self.tracker_settings)
        if "clutter_volume" not in self.tracker_settings:
            base["clutter_volume"] = initiation_region(float(base["v_max"]))  # type: ignore[arg-type]
        base["tracker"], base["depth"] = variant.tracker, variant.depth
        base["psi_init"] = self.psi_for(variant) if psi_init is None else float(psi_init)
        return TrackerConfig.model_validate(base)
