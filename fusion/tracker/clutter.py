"""Clutter density per track × plot row for the existence trackers ([thesis] §2.3.1, (2.35)).

* ``known``: the sensor's (or clutter map's) density at each plot, floored;
* ``estimated``: the non-parametric per-track estimate (2.35 corrected,
  :func:`fusion.tracker.ipda.estimated_clutter_density`) over the gate volume
  V = c_k g^{k/2} √det S̄ of the track-level innovation covariance S̄ = H P Hᵀ + R̄ (the
  predicted density's ``S0`` plus the batch's mean plot covariance). m̂ counts the plots
  inside that same ellipse around the track-level ȳ (``z_mean``), not the union of the
  component gates (:func:`~fusion.tracker.ipda.plots_in_track_gate`); an optional
  ``volume_floor`` reads V_k as max(gate, floor), e.g. the two-point initiation region
  π (v_max T)² of the thesis experiments (docs/reproduction.md).

Units: plots per m² (2-D) or per m³ (3-D).
"""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.association.gating import gate_volume

from .ipda import estimated_clutter_density, plots_in_track_gate


def clutter_density(
    kind: str,
    plot_density: np.ndarray,
    floor: float,
    tp_track: np.ndarray,
    tp_plot: np.ndarray,
    S0: np.ndarray,
    R: np.ndarray,
    pdpg: np.ndarray,
    psi_det: np.ndarray,
    g: float,
    z: np.ndarray | None = None,
    z_mean: np.ndarray | None = None,
    volume_floor: float | None = None,
) -> np.ndarray:
    """ρ per table row. plot_density (m,) the sensor density at each plot; S0 (s, k, k) the
    tracks' H P Hᵀ; R (m, k, k) plot covariances; pdpg, psi_det (s,) per track; z (m, k)
    the plots and z_mean (s, k) the tracks' predicted measurement (both needed to count
    the plots in the track-level gate; without them the gated rows are counted)."""
    rho_plot = np.maximum(np.asarray(plot_density, dtype=np.float64), floor)
    if kind == "known":
        return rho_plot[tp_plot]
    if kind != "estimated":
        raise ValueError(f"clutter = {kind!r}: must be 'known' or 'estimated'")
    ns, k = len(S0), R.shape[-1]
    m_trk = np.bincount(tp_track, minlength=ns)
    R_nom = R.mean(axis=0) if len(R) else np.eye(k)
    S_bar = S0 + R_nom
    if z is not None and z_mean is not None and len(tp_track):
        nu = z[tp_plot] - z_mean[tp_track]
        d2 = np.einsum("pi,pi->p", nu, np.linalg.solve(S_bar[tp_track], nu[..., None])[..., 0])
        m_trk = plots_in_track_gate(d2, tp_track, ns, g, m_trk)
    vol = gate_volume(S_bar, g) if ns else np.zeros(0)
    vol = np.maximum(vol, volume_floor or 0.0)
    rho_trk = estimated_clutter_density(m_trk, pdpg, psi_det, vol, floor)
    return rho_trk[tp_track]
