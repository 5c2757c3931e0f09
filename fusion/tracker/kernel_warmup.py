"""Load the tracker's compiled (numba) kernels before the first batch.

numba compiles a kernel, or loads it from its on-disk cache (``cache=True``), at its
first call in a process. For the tracker's kernels that took 0.5–1.3 s in a fresh
process on the development machine with the cache present, and 23 s without one (the
first run after an installation, or a cache directory numba cannot write: see the image's
``NUMBA_CACHE_DIR``, docs/deployment.md), paid by whichever batch first calls them: in
the live fusion service, latency on its first batches (a profile of the service at
20,000 plots/s had 7.9 % of its samples in numba's dispatcher).

:func:`warm_up` calls each kernel once on a tiny valid input of the one signature the
tracker uses (float64 / int64, C-contiguous: the wrappers pass nothing else), so a
service can pay this at start, before it declares itself alive. It computes nothing that
is kept. The kernels every tracker uses are called here (gating, the Joseph covariance,
moment matching, the existence chain, plot validity, the out-of-sequence noise terms, the
re-identification fix test, the sensor registration's, the passes of a step outside the
densities: pairing, shared plots, the track table, the slots of rows); those of a density
are called by the density's own ``warm_up``, which the registry calls for every
registered density (:func:`fusion.tracker.registry.warm_up_parts`), so a new density needs
no line here. No
equations here: the kernels are documented where they are defined
(:mod:`fusion.association.gating_kernels`, :mod:`fusion.filters.cholesky_kernels`,
:mod:`fusion.filters.kalman`, :mod:`fusion.filters.moment_matching`,
:mod:`fusion.tracker.oosm_kernel`, :mod:`fusion.tracker.reidentification`,
:mod:`fusion.tracker.existence`, :mod:`fusion.tracker.plot_validity_kernel`,
:mod:`fusion.registration.bias_filter_kernel`, :mod:`fusion.registration.pairing_kernel`).
"""

from __future__ import annotations

import time

import numpy as np
from skyfuse.fusion.association.gating import gate
from skyfuse.fusion.filters.cholesky_kernels import positive_definite
from skyfuse.fusion.filters.kalman import joseph_covariance
from skyfuse.fusion.filters.moment_matching import moment_match
from skyfuse.fusion.registration.bias_filter_kernel import gate_and_update
from skyfuse.fusion.registration.pairing_kernel import pair_residuals, partner_rows

from .component_slots import ComponentSlots
from .components import Mixture
from .density.gaussian_mixture import track_table
from .existence import markov_chain_one
from .initiation import PlotBuffer, pair_plots
from .ipda import single_target
from .lm_its import modified_clutter_density
from .management import shared_plot_pairs
from .oosm import noise_terms
from .phases import most_likely_plots
from .plot_validity_kernel import all_plots_valid
from .registry import warm_up_parts
from .reidentification import keeps_fix, update_fix_columns


def warm_up() -> float:
    """Call every compiled kernel once (2 states, d = 2), those of every registered
    density included; return the seconds it took (near zero when they are already loaded
    in this process)."""
    t0 = time.perf_counter()
    eye = np.eye(2)
    P = np.stack([eye, 2.0 * eye])
    positive_definite(P)
    all_plots_valid(np.zeros((2, 2)), P, np.zeros(2))
    keeps_fix(P, np.zeros(2, np.int64), P, np.ones(2, np.int64), 4.0)
    y = np.zeros((2, 2))
    gate(y, P, y + 0.5, P, 9.0)  # gating_kernels (k = 2)
    gate(np.zeros((1, 3)), np.eye(3)[None], np.zeros((1, 3)), None, 9.0)  # and k = 3
    K = np.full((2, 2, 1), 0.5)
    joseph_covariance(P, K, np.array([[1.0, 0.0]]), np.ones((2, 1, 1)))
    w = np.array([0.4, 0.6, 1.0])
    x = np.arange(6.0).reshape(3, 2)
    moment_match(w, x, np.stack([eye, eye, eye]), np.array([0, 0, 1]), 2)
    noise_terms(x[:2], P, 0.1 * P, x[:2] + 1.0, 1.5 * P, np.array([True, True]))
    chain = markov_chain_one(0.98, 0.0)
    chain.predict(np.array([[0.5, 0.0]]), np.array([1.0]))
    chain.existence_below(np.array([[0.5, 0.0]]), np.array([1.0]), 0.1, np.array([True]))
    _tracker_passes(x, P)
    i1 = np.zeros(1, np.int64)
    partner_rows(i1, i1, i1 + 1, i1, i1, i1 + 1, i1, 10)
    v2, m2, h = np.zeros((1, 2)), np.eye(2)[None].copy(), np.zeros((1, 2, 4))
    pair_residuals(i1, i1, v2, v2, v2, h, h, np.zeros((1, 4)), np.zeros((1, 4)), m2, m2, m2, 1.0)
    counts = np.zeros(2, np.int64)
    gate_and_update(np.zeros(8), np.eye(8), np.arange(8) >= 4, np.ones(4), np.ones((1, 2)),
                    eye[None].copy(), np.ones((1, 2, 4)), np.ones((1, 2, 4)),
                    np.array([1]), np.array([0]), 10.0, counts, counts.copy())  # fmt: skip
    warm_up_parts()
    return time.perf_counter() - t0


def _tracker_passes(x: np.ndarray, P: np.ndarray) -> None:
    """The compiled passes of a tracker step outside the densities: the two-point pairing,
    the pairs of tracks sharing a plot, the track × plot table, the slots of track rows
    and their renumbering, the most likely plots, the LM and IPDA association, the
    existence update, the re-identification fixes."""
    i2 = np.array([0, 1])
    buffer = PlotBuffer.empty(2)
    buffer.add(x[:2], P, np.zeros(2, np.int64), i2)
    pair_plots(buffer, x[:2] + 1.0, np.full(2, 10**9), 350.0, 0.5, 15.0, 10**9)
    shared_plot_pairs(i2, np.zeros(2, np.int64))
    track_table(i2, i2, i2, np.ones(2), np.ones(2), 2)
    slots = ComponentSlots.holding(Mixture(i2, np.ones(2), x[:2], P, np.zeros((2, 1), np.int64)))
    slots.rows(np.array([1]), 2)
    slots.keep(np.array([True, False]))
    most_likely_plots(2, i2, np.full(2, 0.5), np.ones(2), i2, i2)
    lm = modified_clutter_density(i2, i2, 2, np.ones(2), np.ones(2), np.full(2, 0.5), np.ones(2))
    single_target(np.full(2, 0.5), np.full(2, 0.9), i2, lm)
    markov_chain_one(0.98, 0.0).update(np.array([[0.5, 0.0]]), np.array([0.6]))
    t2 = np.ones(2, np.int64)
    update_fix_columns(i2, t2, x[:2], P, x[:2].copy(), P.copy(), t2.copy(), 60.0, 4.0)
