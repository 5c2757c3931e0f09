"""``TrackerConfig``: every tunable of the existence-based trackers, with working defaults.

The thesis leaves g, P_G, v_max, ψ_init, τ_t and the pruning threshold open (spec 02 §10,
spec 03 §2); the defaults here are the **[IMPL]** choices documented next to each field.
The model is plain pydantic so the fusion service and ``skyfuse track`` can load it from
TOML (``services.config.build_config(TrackerConfig, toml_path=...)``).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

TrackerKind = Literal["gnn", "ipda", "its", "lmipda", "lmits", "jipda", "jits"]

#: Trackers whose Singer memory depth is fixed at 0 (a single Gaussian per track).
SINGLE_GAUSSIAN_KINDS = ("gnn", "ipda", "lmipda", "jipda")


class TrackerConfig(BaseModel):
    """Configuration of :class:`fusion.tracker.Tracker` (units: metres, seconds, radians)."""

    model_config = ConfigDict(extra="forbid")

    tracker: TrackerKind = Field(
        "lmits",
        description="Association: gnn, ipda, its, lmipda, lmits, jipda or jits",
    )
    depth: int = Field(
        3, ge=0, le=12, description="Singer memory depth N of its/lmits/jits (0 = IPDA)"
    )
    ndim: int = Field(2, ge=2, le=3, description="Measured position dimensions (2 or 3)")
    q: float = Field(
        25.0,
        ge=0.0,
        description="CV acceleration variance, m²/s⁴ (25: turning aircraft; thesis 0.75)",
    )
    q_vertical: float | None = Field(
        None, ge=0.0, description="Vertical acceleration variance (ndim=3), m²/s⁴"
    )
    p_gate: float = Field(
        0.99, gt=0.5, lt=1.0, description="Gate probability P_G (g = chi² quantile)"
    )
    psi_init: float = Field(0.02, gt=0.0, lt=1.0, description="Existence of a new track ψ_init")
    tau_confirm: float = Field(
        0.95, gt=0.0, lt=1.0, description="Confirmation threshold τ_c on existence"
    )
    tau_terminate: float = Field(
        1e-3, gt=0.0, lt=1.0, description="Termination threshold τ_t on existence"
    )
    max_coast: float | None = Field(
        120.0,
        gt=0.0,
        description="Terminate a track that no plot has updated for this long, s (a track "
        "outside every radar's coverage is never eroded by misses); None: existence alone",
    )
    confirm_min_updates: int = Field(
        2,
        ge=0,
        description="Scans with a plot (weight > 0.5) after initiation before confirmation "
        "(spec 02 §8: above τ_c 'long enough')",
    )
    initiation: Literal["two_point", "one_point", "none"] = Field(
        "two_point", description="Track initiation: two_point (3.25-3.27), one_point, none"
    )
    v_max: float = Field(
        350.0, gt=0.0, description="Maximum target speed for two-point pairing, m/s"
    )
    init_min_dt: float = Field(
        0.5, ge=0.0, description="Shortest time between the two plots of a pair, s"
    )
    init_max_dt: float = Field(
        15.0, gt=0.0, description="Longest time an unused plot waits for a partner, s"
    )
    prune_threshold: float = Field(
        1e-3, ge=0.0, lt=1.0, description="Delete components with weight ξ below this"
    )
    max_components: int = Field(30, ge=1, description="Cap on mixture components per track")
    jipda_max_events: int = Field(
        5000, ge=1, description="Largest cluster event count enumerated exactly by JIPDA/JITS"
    )
    existence_chain: Literal["mc1", "mc2"] = Field(
        "mc1", description="Markov chain one (mc1) or two (mc2) for existence"
    )
    delta11: float = Field(
        0.98, gt=0.0, le=1.0, description="P(exists at t+T | exists at t), Δ11, per period"
    )
    delta21: float = Field(
        0.0, ge=0.0, lt=1.0, description="P(exists at t+T | not at t), Δ21, per period"
    )
    existence_period: float = Field(
        1.0, gt=0.0, description="Period T the Markov chain probabilities refer to, s"
    )
    mc2_obs_to_unobs: float = Field(
        0.05, ge=0.0, lt=1.0, description="MC2: P(detectable → not detectable) per period"
    )
    mc2_unobs_to_obs: float = Field(
        0.5, ge=0.0, le=1.0, description="MC2: P(not detectable → detectable) per period"
    )
    clutter: Literal["known", "estimated"] = Field(
        "known", description="Clutter density from the sensor (known) or per track (estimated)"
    )
    clutter_density_floor: float = Field(
        1e-10, gt=0.0, description="Smallest clutter density used, plots per m² (per m³ in 3-D)"
    )
    clutter_volume: float | None = Field(
        None,
        gt=0.0,
        description="Estimated clutter (2.35): V_k = max(gate of S, this), m² (m³ in 3-D); "
        "None: the gate ellipse of the track's S",
    )
    lm_prior_density: Literal["canonical", "thesis"] = Field(
        "canonical", description="LM-IPDA prior (6.12) with plain ρ (canonical) or ρ^τ (6.13)"
    )
    duplicate_p: float = Field(
        0.99, gt=0.0, lt=1.0, description="Chi² probability of the duplicate-track test"
    )
    coverage_sigma: float = Field(
        3.0, ge=0.0, description="Tracks within this many σ of a sector are treated as seen"
    )

    @model_validator(mode="after")
    def _check(self) -> TrackerConfig:
        if self.tau_terminate >= self.tau_confirm:
            raise ValueError(
                f"tau_terminate = {self.tau_terminate} must be below tau_confirm = "
                f"{self.tau_confirm}"
            )
        if self.psi_init >= self.tau_confirm:
            raise ValueError(
                f"psi_init = {self.psi_init} must be below tau_confirm = {self.tau_confirm}"
            )
        if self.init_min_dt >= self.init_max_dt:
            raise ValueError(
                f"init_min_dt = {self.init_min_dt} s must be below init_max_dt = "
                f"{self.init_max_dt} s"
            )
        return self

    @property
    def memory_depth(self) -> int:
        """Effective Singer depth: 0 for the single-Gaussian trackers."""
        return 0 if self.tracker in SINGLE_GAUSSIAN_KINDS else self.depth

    @property
    def association(self) -> str:
        """The association family: gnn, single (IPDA/ITS), lm or joint."""
        return {
            "gnn": "gnn",
            "ipda": "single",
            "its": "single",
            "lmipda": "lm",
            "lmits": "lm",
            "jipda": "joint",
            "jits": "joint",
        }[self.tracker]
