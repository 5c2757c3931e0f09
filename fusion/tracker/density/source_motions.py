"""Motion densities of the filters compared in [MZD] (and [Dikić]'s three-model IMM), as
IMM densities (:class:`~fusion.tracker.density.imm_mixture.IMMMixtureDensity`) behind the
registry's motion names, so that any tracker kind runs them (the crossing-4g baseline:
``gnn`` with ``life_cycle = "m_of_n"``):

* ``singer`` — the Singer KF ([MZD] eq. 8-10; Singer 1970): one Singer mode, τ =
  ``imm_singer_tau``, σ_m = ``imm_singer_sigma_m``, Π = [[1]] (no interaction: a KF in
  the Singer layout [x, vx, ax, …], output in the CV layout);
* ``imm-pcwpa`` — the two-model IMM of [MZD] eq. 11-13: two PCWPA (CV) modes with
  Q = G σ_j² Gᵀ, σ₁ = g/2 (gentle manoeuvres) and σ₂ = 2g (sharp ones), transition
  matrix ``imm_tpm`` per ``imm_tpm_period`` (the source prints p11 = 0.95, p12 = 0.05,
  p21 = 0.9, p22 = 0.1: :data:`SOURCE_TPM_IMM2`), new tracks with ``imm_mu0``;
* ``imm-cv-singer-ct`` — [Dikić]'s three-model IMM: CV (q = ``imm_q_cv``), Singer
  (``imm_singer_*``) and coordinated turn (``imm_ct_*``) mixed in the Singer layout
  ([Dikić] eq. 22), 3 × 3 ``imm_tpm`` and three ``imm_mu0``.

The KF of [MZD] (PCWPA, one mode) is the ``cv`` motion with q = σ².
"""

from __future__ import annotations

from skyfuse.fusion.models import ConstantVelocity, CoordinatedTurn, Singer

from .imm_mixture import IMMMixtureDensity, configured_density

G0 = 9.80665
"""Standard gravity, m/s² ([MZD] rounds it to 10)."""
SOURCE_TPM_IMM2 = (0.95, 0.05, 0.9, 0.1)
"""[MZD] eq. 13 as printed (row-major p11, p12, p21, p22): the manoeuvre mode is left at
once."""
TYPICAL_TPM_IMM2 = (0.95, 0.05, 0.1, 0.9)
"""The usual choice with a persistent manoeuvre mode, p22 = 0.9."""
PCWPA_SIGMAS = (G0 / 2, 2 * G0)
"""σ₁, σ₂ of the two PCWPA modes of [MZD] eq. 12, m/s²."""


def _cv(cfg, q: float) -> ConstantVelocity:
    vertical = cfg.ndim == 3
    qv = cfg.q_vertical if cfg.q_vertical is not None else q
    return ConstantVelocity(q=q, ndim=cfg.ndim, q_vertical=qv if vertical else None)


def _singer(cfg) -> Singer:
    return Singer(tau=cfg.imm_singer_tau, sigma_m=cfg.imm_singer_sigma_m, ndim=cfg.ndim)


def _modes_of(cfg, r: int, motion: str) -> None:
    if len(cfg.imm_mu0) != r:
        raise ValueError(
            f"motion {motion!r} has {r} modes: imm_mu0 = {cfg.imm_mu0} must have {r} entries "
            f"and imm_tpm {r * r}"
        )


def singer_density(cfg) -> IMMMixtureDensity:
    """The Singer KF as a one-mode IMM density (see the module docstring)."""
    return configured_density(cfg, [_singer(cfg)], [1.0], [1.0])


def imm_pcwpa_density(cfg) -> IMMMixtureDensity:
    """[MZD]'s two-model PCWPA IMM (σ = g/2 and 2g; see the module docstring)."""
    _modes_of(cfg, 2, "imm-pcwpa")
    modes = [_cv(cfg, s**2) for s in PCWPA_SIGMAS]
    return configured_density(cfg, modes, cfg.imm_tpm, cfg.imm_mu0)


def imm_cv_singer_ct_density(cfg) -> IMMMixtureDensity:
    """[Dikić]'s three-model IMM, CV + Singer + coordinated turn (module docstring)."""
    _modes_of(cfg, 3, "imm-cv-singer-ct")
    qv = cfg.q_vertical if cfg.q_vertical is not None else cfg.imm_q_cv
    ct = CoordinatedTurn(
        cfg.imm_ct_sigma_a, cfg.imm_ct_sigma_omega, vertical=cfg.ndim == 3, q_vertical=qv
    )
    modes = [_cv(cfg, cfg.imm_q_cv), _singer(cfg), ct]
    return configured_density(cfg, modes, cfg.imm_tpm, cfg.imm_mu0)
