"""Resampling of many particle clouds at once ([thesis] (3.51–3.55); Arulampalam et al. 2002).

Every scheme takes normalised weights ``w`` (n_clouds, N) and returns ancestor indices
(n_clouds, N) into each cloud's own particles, sorted ascending within a row; after
resampling all weights are 1/N. All are unbiased, E[N_i] = N w_i for the offspring count
N_i of particle i; they differ in Var N_i:

* **systematic** ([thesis] (3.51–3.55)): one u ~ U[0, 1/N) per cloud, u_l = u + (l − 1)/N, take
  the i with c_{i−1} < u_l ≤ c_i (c = cumsum w). The number of u_l ≤ c_i is
  ⌊N c_i − N u⌋ + 1, so offspring counts are differences of that, exact and O(N) per
  cloud with no search. N_i ∈ {⌊N w_i⌋, ⌈N w_i⌉}: Var N_i = f(1 − f), f = frac(N w_i).
* **stratified**: u_l ~ U[(l − 1)/N, l/N) independently; Var N_i = Σ_l a_l (1 − a_l)
  with a_l the length of stratum l inside (N c_{i−1}, N c_i].
* **multinomial** by ordered uniforms: ũ_N = u_N^{1/N}, ũ_i = ũ_{i+1} u_i^{1/i}
  are the order statistics of N uniforms without a sort (computed as a reversed cumulative
  sum of log u_i / i); one walk over c gives N i.i.d. draws. Var N_i = N w_i (1 − w_i).
* **residual**: ⌊N w_i⌋ copies deterministically, the remaining R = N − Σ⌊N w_i⌋ drawn
  multinomially from w̄_i = (N w_i − ⌊N w_i⌋)/R; Var N_i = R w̄_i (1 − w̄_i).

The walk over c for random u is one ``searchsorted`` on all clouds at once: cloud r's
cumulative weights and uniforms are shifted by r, so the flattened arrays stay sorted
(resolution ~1e-16·n_clouds in weight, far below 1/N).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def _cumulative(w: np.ndarray) -> np.ndarray:
    c = np.cumsum(w, axis=1)
    c /= c[:, -1:]
    c[:, -1] = 1.0
    return c


def counts_to_indices(counts: np.ndarray) -> np.ndarray:
    """Ancestor indices (n, N) from offspring counts (n, N) whose rows sum to N."""
    n, N = counts.shape
    return np.repeat(np.tile(np.arange(N), n), counts.ravel()).reshape(n, N)


def _search_counts(c: np.ndarray, u: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
    """Offspring counts (n, N): how many u[r] fall in each (c[r, i−1], c[r, i]]; u (n, M)."""
    n, N = c.shape
    off = np.arange(n)[:, None]
    idx = np.searchsorted((c + off).ravel(), (np.minimum(u, 1.0) + off).ravel(), side="left")
    first = (off * N).repeat(u.shape[1], axis=1).ravel()
    idx = np.clip(idx, first, first + N - 1)  # u = 0 or 1 exactly stays in its own cloud
    weights = None if valid is None else valid.ravel().astype(np.float64)
    return np.bincount(idx, weights=weights, minlength=n * N).reshape(n, N).astype(np.int64)


def systematic_counts(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Offspring counts (n, N) of systematic resampling ([thesis] (3.51–3.55))."""
    n, N = w.shape
    u = rng.random((n, 1))  # N u_1, in [0, 1)
    below = np.clip(np.floor(N * _cumulative(w) - u).astype(np.int64) + 1, 0, N)
    return np.diff(below, axis=1, prepend=0)


def systematic(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Systematic resampling ([thesis] (3.51–3.55)): ancestor indices (n, N)."""
    return counts_to_indices(systematic_counts(w, rng))


def stratified(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Stratified resampling: one uniform in each stratum [(l−1)/N, l/N); indices (n, N)."""
    n, N = w.shape
    u = (np.arange(N) + rng.random((n, N))) / N
    return counts_to_indices(_search_counts(_cumulative(w), u))


def ordered_uniforms(rng: np.random.Generator, n: int, N: int, sizes=None) -> np.ndarray:
    """Ascending order statistics of i.i.d. U(0, 1) per row without sorting.

    log ũ_i = Σ_{j=i}^{M} log(u_j)/j for a row of M = ``sizes[r]`` (default N) uniforms;
    entries beyond M are 1 (to be masked by the caller). Returns (n, N)."""
    j = np.arange(1, N + 1)
    terms = np.log1p(-rng.random((n, N))) / j  # log of u ~ U(0, 1]
    if sizes is not None:
        terms = np.where(j[None, :] <= np.asarray(sizes)[:, None], terms, 0.0)
    return np.exp(np.cumsum(terms[:, ::-1], axis=1)[:, ::-1])


def multinomial(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Multinomial resampling by the ordered-uniform walk: indices (n, N)."""
    n, N = w.shape
    u = ordered_uniforms(rng, n, N)
    return counts_to_indices(_search_counts(_cumulative(w), u))


def residual(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Residual resampling: ⌊N w⌋ copies plus a multinomial draw of the remainder."""
    n, N = w.shape
    base = np.floor(N * w).astype(np.int64)
    rest = N - base.sum(axis=1)
    frac = N * w - base
    has_rest = rest > 0
    frac[~has_rest] = 1.0  # rows with no remainder: any valid cumulative, nothing drawn
    u = ordered_uniforms(rng, n, N, sizes=rest)
    valid = np.arange(N)[None, :] < rest[:, None]
    return counts_to_indices(base + _search_counts(_cumulative(frac), u, valid))


SCHEMES: dict[str, Callable[[np.ndarray, np.random.Generator], np.ndarray]] = {
    "systematic": systematic,
    "stratified": stratified,
    "multinomial": multinomial,
    "residual": residual,
}


def resample(w: np.ndarray, rng: np.random.Generator, scheme: str = "systematic") -> np.ndarray:
    """Ancestor indices (n, N) by the named scheme (one of :data:`SCHEMES`)."""
    try:
        fn = SCHEMES[scheme]
    except KeyError:
        raise ValueError(f"scheme = {scheme!r}: must be one of {sorted(SCHEMES)}") from None
    return fn(np.atleast_2d(w), rng)


def take(x: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Particles (n, N, d) gathered by ancestor indices (n, N) cloud by cloud."""
    n, N, d = x.shape
    flat = (idx + N * np.arange(n)[:, None]).ravel()
    return x.reshape(n * N, d)[flat].reshape(n, idx.shape[1], d)
