"""Surface-movement motion (``imm-surface``): an IMM for aircraft and vehicles on an airport
surface, which also carries airborne traffic, as an IMM density
(:class:`~fusion.tracker.density.imm_mixture.IMMMixtureDensity`; the IMM of H. A. P. Blom
and Y. Bar-Shalom, IEEE Trans. AC 33(8), 1988, and Bar-Shalom, Li and Kirubarajan,
*Estimation with Applications to Tracking and Navigation*, 2001, ch. 11) with three
modes, x east, y north (z up in 3-D), m, m/s, s:

1. **CV** — nearly constant velocity (Bar-Shalom et al. 2001 §6.3.2; :mod:`fusion.models.cv`):
   F_T = [[1, T], [0, 1]], Q_T = q_cv [[T⁴/4, T³/2], [T³/2, T²]] per axis, q_cv =
   ``surface_q_cv`` (m²/s⁴): taxiing at 5–15 m/s, the take-off and landing runs
   (1.5–3 m/s²) and straight flight;
2. **stopped** — the damped velocity of :mod:`fusion.models.damped_velocity`:
   F_T = [[1, b], [0, e]], Q_T = q_s [[c², cb], [cb, b²]], e = e^{−βT},
   b = (1 − e)/β, c = (T − b)/β, β = ``surface_stop_damping`` (1/s), q_s =
   ``surface_stop_q`` (m²/s⁴): a target parked, holding short or stopped in a queue for
   minutes, whose estimate averages the plots instead of following their noise (in 3-D
   the vertical axis is damped with the same q_s);
3. **turn** — the nearly coordinated turn (x, y, ψ, ω, v) of
   :mod:`fusion.models.coordinated_turn` (ẋ = v cos ψ, ẏ = v sin ψ, ψ̇ = ω; white
   tangential acceleration σ_a = ``surface_ct_sigma_a`` m/s² and turn-rate acceleration
   σ_ω = ``surface_ct_sigma_omega`` rad/s²): taxiway junctions of radius 30–60 m at
   5–15 m/s (ω up to 0.3–0.4 rad/s, reached within a few seconds: σ_ω = 0.2 rad/s² by
   default, against the 0.03 of ``imm-cv-ct``'s airliner turns) and airborne turns.

Π_T = ``surface_tpm`` (3 × 3, row-major, per ``imm_tpm_period`` s, fractional powers for
other intervals: :class:`~.imm_mixture.ModeTransition`) encodes the dwell times: a stop
lasts minutes, a taxi leg tens of seconds, a turn a few seconds; a stopped target starts
again in CV. The defaults (``TrackerConfig``) were chosen by measurement on the LEBL
recordings (docs/how-to/airport-surface.md, "Surface motion"): a stop is left with 0.10
per 4 s (a stickier 0.03 gave 2.10 track ids per aircraft against 1.85 on LEBL 2016
fused). New tracks start with ``surface_mu0``. Mixing is in the common layout of
[Dikić] eq. 22 (the turn mode's (ψ, ω, v) against the velocities of the two CV-layout
modes). Every other setting (memory, pruning, coasting, reachability,
gating) is the IMM density's; on a long coast (``imm_coast_after``) the stopped and turn
modes take the CV mode's prediction, as the manoeuvre modes of ``imm-cv-ct`` do (keeping
the stopped mode's own prediction instead measured the same on the LEBL recordings).
"""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.models import ConstantVelocity, CoordinatedTurn
from skyfuse.fusion.models.damped_velocity import DampedVelocity

from .imm_mixture import IMMMixtureDensity, configured_density

MODES = ("cv", "stopped", "turn")
"""The modes of ``imm-surface`` in the order of ``surface_tpm`` and ``surface_mu0``."""


def surface_modes(cfg) -> list:
    """The three mode models of a TrackerConfig (module docstring), 2-D or 3-D."""
    ndim = cfg.ndim
    qv = cfg.q_vertical if cfg.q_vertical is not None else cfg.surface_q_cv
    cv = ConstantVelocity(q=cfg.surface_q_cv, ndim=ndim, q_vertical=qv if ndim == 3 else None)
    stopped = DampedVelocity(q=cfg.surface_stop_q, ndim=ndim, damping=cfg.surface_stop_damping)
    turn = CoordinatedTurn(
        cfg.surface_ct_sigma_a, cfg.surface_ct_sigma_omega, vertical=ndim == 3, q_vertical=qv
    )
    return [cv, stopped, turn]


def imm_surface_density(cfg) -> IMMMixtureDensity:
    """The ``imm-surface`` IMM density of a TrackerConfig (module docstring)."""
    return configured_density(cfg, surface_modes(cfg), cfg.surface_tpm, cfg.surface_mu0)


def warm_up() -> None:
    """Load the stopped mode's compiled prediction (the other modes' kernels are the IMM
    density's warm-up)."""
    stopped = DampedVelocity(q=0.01, damping=1.0)
    stopped.predict(np.zeros((1, 4)), np.eye(4)[None], 1.0)
    stopped.F(1.0)  # its terms alone (the retrodiction's F and Q)
    IMMMixtureDensity.warm_up()
