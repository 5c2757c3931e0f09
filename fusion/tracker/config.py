"""``TrackerConfig``: every tunable of the existence-based trackers, with working defaults.

The thesis leaves g, P_G, v_max, ψ_init, τ_t and the pruning threshold open ([thesis]
ch. 7); the defaults here are the **[IMPL]** choices documented next to each field.
The tracker kinds and motions are the registry's (:mod:`.registry`), shipped or
registered later.
The model is plain pydantic so the fusion service and ``skyfuse track`` can load it from
TOML (``services.config.build_config(TrackerConfig, toml_path=...)``).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from .registry import (
    MOTIONS,
    TRACKERS,
    motion_help,
    own_density_kinds,
    single_gaussian_kinds,
    tracker_help,
)

#: Tracker kinds and motion densities, derived from :mod:`fusion.tracker.registry` (the
#: parts shipped; a part registered later is accepted too, see ``_registered``).
TrackerKind = Literal[tuple(TRACKERS)]  # type: ignore[valid-type]
MotionKind = Literal[tuple(MOTIONS)]  # type: ignore[valid-type]

#: Trackers whose Singer memory depth is fixed at 0 (a single Gaussian per track).
SINGLE_GAUSSIAN_KINDS = single_gaussian_kinds()


class TrackerConfig(BaseModel):
    """Configuration of :class:`fusion.tracker.Tracker` (units: metres, seconds, radians)."""

    model_config = ConfigDict(extra="forbid")

    tracker: TrackerKind = Field(
        "lmits",
        description="Tracker: " + tracker_help(),
    )
    motion: MotionKind = Field(
        "imm-cv-ct",
        description="Motion density: " + motion_help() + " (imm-cv-ct chosen by measurement, "
        "docs/reports/tracker-log.md)",
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
        "([thesis] §7.1: above τ_c 'long enough')",
    )
    life_cycle: Literal["existence", "m_of_n"] = Field(
        "existence",
        description="Confirmation and termination by existence (tau_confirm, tau_terminate) or "
        "by counting scans (m_of_n: confirm_m_of_n, max_misses; the classical GNN life cycle, "
        "existence is then computed but decides nothing)",
    )
    confirm_m_of_n: list[int] = Field(
        [2, 3],
        description="life_cycle m_of_n: confirm a tentative track with a plot in M of its first "
        "N scans in coverage (the scan that started it is one), delete it when it no longer can",
    )
    max_misses: int = Field(
        3,
        ge=1,
        description="life_cycle m_of_n: end a confirmed track after this many consecutive scans "
        "in coverage without a plot",
    )
    initiation: Literal["two_point", "one_point", "none"] = Field(
        "two_point", description="Track initiation: two_point (3.25-3.27), one_point, none"
    )
    init_free_weight: float | None = Field(
        None,
        gt=0.0,
        le=1.0,
        description="A plot may start a track when the tracks' association weights Σβ on it "
        "are below this (None: only plots no track gated)",
    )
    v_max: float = Field(
        350.0,
        gt=0.0,
        description="Maximum target speed, m/s: two-point pairing and the IMM reachability "
        "gate (reach_gate)",
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
    oosm: bool = Field(
        True,
        description="Out-of-sequence update of plots older than a track's time (retrodiction, "
        "Bar-Shalom 2002 A1, fusion/tracker/oosm.py); off: applied at the track's time",
    )
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
    duplicate_survivor: Literal["existence", "established"] = Field(
        "existence",
        description="Of two confirmed duplicate tracks, keep the larger ψ (existence, [thesis] "
        "§7.1) or the one with more scans with a plot and its id (established)",
    )
    report_sensors: int = Field(
        8,
        ge=1,
        le=64,
        description="Report-based sensors (ADS-B, multilateration) one tracker follows: each "
        "has a slot in the tracks' report clock (fusion/tracker/report_clock.py)",
    )
    coverage_sigma: float = Field(
        3.0, ge=0.0, description="Tracks within this many σ of a sector are treated as seen"
    )
    blind_share: float = Field(
        0.05,
        ge=0.0,
        lt=1.0,
        description="A track whose probability of being below the radar's maximum elevation "
        "is under this is in the cone of silence: it coasts and its max_coast clock restarts",
    )
    reid_max_gap: float | None = Field(
        180.0,
        gt=0.0,
        description="Re-identification: a newly confirmed track takes the id of a confirmed "
        "track terminated after its last plot at most this long ago, s, when their kinematics "
        "agree unambiguously (fusion/tracker/reidentification.py); None: off",
    )
    reid_q: float = Field(
        4.0,
        ge=0.0,
        description="Re-identification: continuous white-noise acceleration spectral density "
        "of the terminated track's prediction, m²/s³",
    )
    reid_max_sigma: float = Field(
        5000.0,
        gt=0.0,
        description="Re-identification: largest per-axis position σ of the terminated track's "
        "prediction that may still continue it, m",
    )
    reid_min_speed: float = Field(
        15.0,
        ge=0.0,
        description="Re-identification: both tracks must move at least this fast, m/s (about "
        "the highest taxi speed, 30 kt: parked and taxiing aircraft are not told apart by "
        "kinematics)",
    )
    reid_live_gap: float | None = Field(
        10.0,
        gt=0.0,
        description="Re-identification of a live track: a newly confirmed track that started "
        "after the last plot of a confirmed track, at most this long before, s, and agrees "
        "with it by the re-identification test (with reid_live_q) takes its id and ends it "
        "(fusion/tracker/reidentification.py, L1-L3; 10 s chosen by measurement on the LEBL "
        "recording, 5-20 s measure the same); None: terminated tracks only",
    )
    reid_live_q: float = Field(
        600.0,
        ge=0.0,
        description="Re-identification of a live track: reid_q for the prediction of its last "
        "fix, m²/s³ (600: the fix of a track that an outlier pulled or a coverage hole ended "
        "is 100-350 m and 20-60 m/s off within seconds, measured on LEBL; 600-2000 measure "
        "the same)",
    )
    reid_live_existence: float = Field(
        0.1,
        gt=0.0,
        le=1.0,
        description="Re-identification of a live track: only a track whose existence is below "
        "this may be continued (the tracker doubts it; LEBL continuations: 0.006-0.05)",
    )
    reid_p: float = Field(
        0.99, gt=0.0, lt=1.0, description="Re-identification: chi² probability of the gate"
    )

    identity: bool = Field(
        True,
        description="Attribute the plots' secondary-surveillance identity to the tracks "
        "(Mode-3/A, Mode-S address, callsign, flight level, SPI, downlinked parameters; "
        "fusion/tracker/identity.py); it never drives association",
    )
    identity_confirm: int = Field(
        2,
        ge=1,
        description="Identity: sightings in a row of a new code (validated, ungarbled) "
        "before it replaces the track's code",
    )
    identity_conflict_window: float = Field(
        60.0,
        gt=0.0,
        description="Identity: a Mode-S address or callsign other than the track's, seen "
        "within this long of the last confirmation of the track's, is a conflict (two "
        "aircraft on one track: a swap or a merge), s",
    )
    identity_change_hold: float = Field(
        30.0,
        ge=0.0,
        description="Identity: a track's Mode-3/A code counts as changed (CAT062 I062/060 "
        "CH) for this long after the change, s",
    )

    # IMM densities (motion = imm-cv-ct | imm-cv-singer; [Dikić], [MZD]) [IMPL] defaults for
    # civil aircraft: straight flight in a quiet CV mode, 2.5-3 g turns (ω ≈ 0.1-0.2 rad/s
    # at 150-300 m/s) in the turn mode, for 4 s and 10-12 s scan periods.
    imm_q_cv: float = Field(4.0, ge=0.0, description="IMM: CV-mode acceleration variance, m²/s⁴")
    imm_ct_sigma_a: float = Field(
        1.0, ge=0.0, description="IMM: turn-mode tangential acceleration σ, m/s²"
    )
    imm_ct_sigma_omega: float = Field(
        0.03, gt=0.0, description="IMM: turn-mode turn-rate acceleration σ, rad/s²"
    )
    imm_singer_tau: float = Field(10.0, gt=0.0, description="IMM: Singer-mode time constant τ, s")
    imm_singer_sigma_m: float = Field(
        30.0, ge=0.0, description="IMM: Singer-mode acceleration σ_m, m/s² (≈ 3 g)"
    )
    imm_tpm: list[float] = Field(
        [0.95, 0.05, 0.10, 0.90],
        description="IMM mode transition matrix per imm_tpm_period, row-major (p11, p12, p21, p22)",
    )
    imm_tpm_period: float = Field(
        4.0, gt=0.0, description="Period the IMM transition matrix refers to, s"
    )
    imm_mu0: list[float] = Field(
        [0.9, 0.1], description="IMM mode probabilities of a new track (CV, manoeuvre)"
    )
    imm_init_acceleration: float = Field(
        5.0, ge=0.0, description="IMM: acceleration σ of a new track, m/s²"
    )
    imm_coast_after: float | None = Field(
        30.0,
        gt=0.0,
        description="IMM: a prediction over more than this is a coast, s: predicted in steps "
        "of imm_coast_step, then the manoeuvre modes take the CV mode's prediction (a lost "
        "aircraft flies straight; fusion/tracker/density/imm_mixture.py); None: one step",
    )
    imm_coast_step: float = Field(10.0, gt=0.0, description="IMM: step of a coast's prediction, s")
    imm_gating: Literal["per-mode", "mixed"] = Field(
        "per-mode",
        description="IMM: a plot is gated if any mode's gate holds it (per-mode, [MZD] §5) or if "
        "the gate of the mode-mixed prediction does (mixed)",
    )
    # surface-movement IMM (motion = imm-surface; fusion/tracker/density/surface_motion.py)
    # [IMPL] defaults chosen on the LEBL recordings (docs/how-to/airport-surface.md, "Surface
    # motion"): modes CV (taxi and flight), stopped (damped velocity) and tight turn
    # (coordinated turn); surface_tpm per imm_tpm_period.
    surface_q_cv: float = Field(
        4.0, ge=0.0, description="imm-surface: CV-mode acceleration variance, m²/s⁴"
    )
    surface_stop_q: float = Field(
        0.01, ge=0.0, description="imm-surface: stopped-mode acceleration variance, m²/s⁴"
    )
    surface_stop_damping: float = Field(
        1.0, gt=0.0, description="imm-surface: stopped-mode velocity damping β, 1/s"
    )
    surface_ct_sigma_a: float = Field(
        1.0, ge=0.0, description="imm-surface: turn-mode tangential acceleration σ, m/s²"
    )
    surface_ct_sigma_omega: float = Field(
        0.2, gt=0.0, description="imm-surface: turn-mode turn-rate acceleration σ, rad/s²"
    )
    surface_tpm: list[float] = Field(
        [0.90, 0.05, 0.05, 0.10, 0.90, 0.0, 0.30, 0.05, 0.65],
        description="imm-surface: 3x3 mode transition matrix per imm_tpm_period, row-major, "
        "modes (CV, stopped, turn)",
    )
    surface_mu0: list[float] = Field(
        [0.5, 0.3, 0.2],
        description="imm-surface: mode probabilities of a new track (CV, stopped, turn)",
    )
    reach_gate: bool = Field(
        True,
        description="IMM: a plot farther from the track's last fix than v_max × the time "
        "since plus the gate's σ of both is not gated (fusion/tracker/density/imm_mixture.py "
        "ReachGate)",
    )

    # particle trackers ipf / lmipf ([LM-IPF]; fusion/tracker/density/particles.py)
    particles: int = Field(
        1000, ge=1, le=1_000_000, description="ipf/lmipf: particles per track N (source 1000)"
    )
    resample_threshold: float | None = Field(
        None,
        gt=0.0,
        le=1.0,
        description="ipf/lmipf: resample a cloud when N_eff < this × N; None: every scan",
    )
    resampling: Literal["systematic", "stratified", "multinomial", "residual"] = Field(
        "systematic", description="ipf/lmipf: resampling scheme (source: systematic)"
    )
    particle_seed: int = Field(0, ge=0, description="ipf/lmipf: seed of the particle noise")

    @field_validator("tracker", "motion", mode="wrap")
    @classmethod
    def _registered(cls, value, handler, info):
        """A name registered after this module was imported (a density or tracker kind
        of another module, e.g. a test's) is accepted as well as the shipped ones."""
        names = TRACKERS if info.field_name == "tracker" else MOTIONS
        if isinstance(value, str) and value in names:
            return value
        return handler(value)

    @model_validator(mode="after")
    def _check(self) -> TrackerConfig:
        if self.tracker in own_density_kinds() and self.motion != "cv":
            if "motion" in self.model_fields_set:
                raise ValueError(
                    f"tracker = {self.tracker!r} has its own density (constant velocity); "
                    f"motion = {self.motion!r} is not available for it"
                )
            self.motion = "cv"  # the default motion does not apply to these kinds
        if self.tau_terminate >= self.tau_confirm:
            raise ValueError(
                f"tau_terminate = {self.tau_terminate} must be below tau_confirm = "
                f"{self.tau_confirm}"
            )
        if self.psi_init >= self.tau_confirm:
            raise ValueError(
                f"psi_init = {self.psi_init} must be below tau_confirm = {self.tau_confirm}"
            )
        r = len(self.imm_mu0)
        if len(self.imm_tpm) != r * r or r < 1 or min(self.imm_mu0) < 0 or sum(self.imm_mu0) <= 0:
            raise ValueError(
                f"imm_tpm has {len(self.imm_tpm)} entries and imm_mu0 = {self.imm_mu0}: need "
                f"{r}x{r} = {r * r} transition probabilities and non-negative mode weights"
            )
        mu = self.surface_mu0
        if len(self.surface_tpm) != 9 or len(mu) != 3 or min(mu) < 0 or sum(mu) <= 0:
            raise ValueError(
                f"surface_tpm has {len(self.surface_tpm)} entries and surface_mu0 = "
                f"{self.surface_mu0}: need 3x3 = 9 transition probabilities and 3 "
                "non-negative mode weights"
            )
        m_of_n = self.confirm_m_of_n
        if len(m_of_n) != 2 or not 1 <= m_of_n[0] <= m_of_n[1]:
            raise ValueError(f"confirm_m_of_n = {m_of_n}: must be [M, N] with 1 <= M <= N")
        if self.init_min_dt >= self.init_max_dt:
            raise ValueError(
                f"init_min_dt = {self.init_min_dt} s must be below init_max_dt = "
                f"{self.init_max_dt} s"
            )
        return self

    @property
    def memory_depth(self) -> int:
        """Effective Singer depth: 0 for the single-Gaussian trackers."""
        return self.depth if TRACKERS[self.tracker].memory else 0

    @property
    def association(self) -> str:
        """The association part of the tracker kind (registry): gnn, single, lm or joint."""
        return TRACKERS[self.tracker].association
