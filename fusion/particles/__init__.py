"""Particle-filter library and the particle primitives of the IPF / LM-IPF trackers
([LM-IPF]; the track density itself is :mod:`fusion.tracker.density.particles`).

All functions work on many clouds at once: particles ``(n_clouds, n_particles, dim)`` and
weights ``(n_clouds, n_particles)``, one row per track (or per Monte Carlo run).

Modules, one concept each:

* :mod:`.weights` — normalisation of log-weights, N_eff = 1/Σw², MMSE moments.
* :mod:`.resampling` — systematic ([thesis] (3.51–3.55)), stratified, multinomial by ordered
  uniforms, residual; all return ancestor indices ``(n_clouds, n_particles)``.
* :mod:`.roughening` — Gordon's roughening jitter after resampling.
* :mod:`.model` — the state-space model protocol the generic filter steps use.
* :mod:`.sir` / :mod:`.sis` / :mod:`.auxiliary` — the filter steps (Arulampalam et al. 2002).
* :mod:`.pcrlb` — Tichavský posterior Cramér–Rao lower bound (Tichavský et al. 1998), with P_D.
* :mod:`.nonlinear_benchmark` — the scalar nonlinear benchmark (docs/reports/particles-log.md).
* :mod:`.likelihood` — per-particle Gaussian plot likelihoods ([LM-IPF] eq. 7-8) for
  gated pairs.
* :mod:`.association` — the IPF association ([LM-IPF] eq. 10-12, 16-17) and the LM step
  (eq. 14-15).
"""
