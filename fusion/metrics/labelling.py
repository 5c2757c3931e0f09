"""Truth labelling of tracks: which target (if any) each track is following, scan by scan.

True/false labels of [thesis] §7.1, eq. (7.1):

1. Every new track is false (``FALSE`` = −1) until it passes the test below.
2. A false track becomes true for target t when the normalised distance of its state from
   the target's state is under the threshold (20), using the **fixed** two-point
   initiation covariance P_{2|2}, not the track's own P_{k|k} (a large-covariance track
   cannot pass)::

       d² = (x̂^τ_{k|k} − x^t_k)ᵀ (P_{2|2})⁻¹ (x̂^τ_{k|k} − x^t_k) < 20            (7.1)

   The state is the tracker state, interleaved ``[x, vx, y, vy(, z, vz)]`` (metres, m/s),
   and P_{2|2} per axis is [[R, R/T], [R/T, 2R/T²]] ([thesis] (3.25-3.27)),
   ``two_point_covariance``. If several targets pass, the track takes the nearest (min d²).
   A new track is tested in its first scan.
3. A true track for t stays true while it **selects** t's detections: in a scan in which any
   of the plots it selected (gated / was updated with) originated from t, it keeps the
   label and no distance test is made.
4. Missed scans (not in the thesis; [IMPL]): a scan in which a true track selects no
   detection of t (t undetected, t absent, or only clutter / other targets' plots in the
   gate) keeps the label and counts a miss. After ``retest_after`` (3) consecutive misses,
   and in every further scan while the misses continue, (7.1) is re-tested: if t still
   passes the label stays t; otherwise the track takes the nearest passing target (a
   **switch**) or becomes false. Selecting a detection of t resets the miss count.

A false track is tested against all targets of the scan every scan. Track ids are the
tracker's ids; a track id absent from a scan is forgotten (terminated).
"""

from __future__ import annotations

import numpy as np

FALSE = -1
"""Label of a track that follows no target."""


def two_point_covariance(R: np.ndarray | float, T: float) -> np.ndarray:
    """Fixed P_{2|2} of two-point differencing initiation ([thesis] §3.5, (3.25-3.27)).

    ``R``: position measurement covariance, scalar (same variance on every axis; then 2-D)
    or ``(ndim, ndim)``, m². ``T``: time between the two plots, s. Returns the interleaved
    ``(2·ndim, 2·ndim)`` covariance: per axis pair (i, j) the block
    R_ij · [[1, 1/T], [1/T, 2/T²]] (so [[25, 25], [25, 50]] for R = 25 m², T = 1 s)."""
    R = np.asarray(R, dtype=np.float64)
    if R.ndim == 0:
        R = R * np.eye(2)
    if R.ndim != 2 or R.shape[0] != R.shape[1]:
        raise ValueError(f"R: shape {R.shape}: must be scalar or (ndim, ndim)")
    if not (np.isfinite(T) and T > 0):
        raise ValueError(f"T = {T}: must be finite and > 0 s")
    block = np.array([[1.0, 1.0 / T], [1.0 / T, 2.0 / T**2]])
    return np.kron(R, block)


def normalised_distance(
    track_states: np.ndarray, truth_states: np.ndarray, P_inv: np.ndarray
) -> np.ndarray:
    """d²[i, j] = (x̂_i − x_j)ᵀ P⁻¹ (x̂_i − x_j) for tracks (m, s) and targets (n, s): (m, n)."""
    diff = track_states[:, None, :] - truth_states[None, :, :]
    return np.einsum("ijk,ijk->ij", diff @ P_inv, diff)


def _as_states(name: str, arr: np.ndarray, s: int) -> np.ndarray:
    a = np.asarray(arr, dtype=np.float64)
    if a.size == 0:
        return np.zeros((0, s))
    if a.ndim != 2 or a.shape[1] != s:
        raise ValueError(f"{name}: shape {a.shape}: must be (n, {s}) states like P_{{2|2}}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: contains non-finite values: states must be finite")
    return a


def _as_id_vector(name: str, arr: np.ndarray, n: int) -> np.ndarray:
    a = np.asarray(arr)
    if a.size == 0:
        a = a.astype(np.int64).reshape(0)
    if a.ndim != 1 or len(a) != n or not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"{name}: shape {a.shape}, dtype {a.dtype}: must be ({n},) integers")
    if len(np.unique(a)) != n:
        raise ValueError(f"{name}: ids must be unique within a scan")
    return a.astype(np.int64)


class TruthLabeller:
    """Stateful truth labelling over scans (rules in the module docstring).

    ``P22``: the fixed (s, s) covariance of (7.1) (``two_point_covariance(25, 1)`` in the
    thesis scenarios). ``threshold``: 20. ``retest_after``: consecutive missed scans before
    (7.1) is re-tested (3). Call ``step`` once per scan, in time order."""

    def __init__(self, P22: np.ndarray, threshold: float = 20.0, retest_after: int = 3) -> None:
        P22 = np.asarray(P22, dtype=np.float64)
        if P22.ndim != 2 or P22.shape[0] != P22.shape[1]:
            raise ValueError(f"P22: shape {P22.shape}: must be square (s, s)")
        try:
            np.linalg.cholesky(P22)
        except np.linalg.LinAlgError as exc:
            raise ValueError("P22: must be symmetric positive definite") from exc
        if not threshold > 0:
            raise ValueError(f"threshold = {threshold}: must be > 0")
        if retest_after < 1:
            raise ValueError(f"retest_after = {retest_after}: must be >= 1 scan")
        self.P_inv = np.linalg.inv(P22)
        self.threshold = float(threshold)
        self.retest_after = int(retest_after)
        self._ids = np.zeros(0, dtype=np.int64)  # sorted track ids of the previous scan
        self._labels = np.zeros(0, dtype=np.int64)
        self._misses = np.zeros(0, dtype=np.int64)

    def step(
        self,
        track_ids: np.ndarray,
        track_states: np.ndarray,
        truth_ids: np.ndarray,
        truth_states: np.ndarray,
        selected_targets: np.ndarray,
        selected_weights: np.ndarray | None = None,
        min_weight: float = 0.0,
    ) -> np.ndarray:
        """Label the m tracks of one scan; returns (m,) target ids, ``FALSE`` (−1) if none.

        ``track_ids`` (m,) integer track ids; ``track_states`` (m, s) estimates x̂_{k|k};
        ``truth_ids`` (n,) target ids (>= 0) present this scan with true states
        ``truth_states`` (n, s). ``selected_targets``: the origin target id of each plot the
        track selected this scan, as (m,) (one plot per track, e.g. the dominant one) or
        (m, q) padded with −1; −1 also stands for clutter or no plot. With
        ``selected_weights`` of the same shape (e.g. association probabilities β), only
        plots with weight > ``min_weight`` count as selected."""
        s = self.P_inv.shape[0]
        tids = _as_id_vector("track_ids", track_ids, len(np.asarray(track_ids)))
        m = len(tids)
        x_hat = _as_states("track_states", track_states, s)
        if len(x_hat) != m:
            raise ValueError(f"track_states: {len(x_hat)} rows: must match track_ids ({m})")
        gids = _as_id_vector("truth_ids", truth_ids, len(np.asarray(truth_ids)))
        if np.any(gids < 0):
            raise ValueError("truth_ids: target ids must be >= 0 (−1 means false/clutter)")
        x_true = _as_states("truth_states", truth_states, s)
        if len(x_true) != len(gids):
            raise ValueError(f"truth_states: {len(x_true)} rows: must match truth_ids")
        sel = np.asarray(selected_targets)
        if sel.size == 0:
            sel = np.full((m, 1), FALSE, dtype=np.int64)
        if sel.ndim == 1:
            sel = sel[:, None]
        if sel.ndim != 2 or sel.shape[0] != m or not np.issubdtype(sel.dtype, np.integer):
            raise ValueError(
                f"selected_targets: shape {sel.shape}, dtype {sel.dtype}: must be ({m},) or "
                f"({m}, q) integer target ids"
            )
        if selected_weights is not None:
            w = np.asarray(selected_weights, dtype=np.float64).reshape(sel.shape)
            sel = np.where(w > min_weight, sel, FALSE)

        d2 = normalised_distance(x_hat, x_true, self.P_inv)  # (m, n)
        passes = d2 < self.threshold
        nearest = np.full(m, FALSE, dtype=np.int64)
        if m and len(gids):
            j = np.argmin(np.where(passes, d2, np.inf), axis=1)
            nearest = np.where(passes.any(axis=1), gids[j], FALSE)

        # Previous label and miss count of each track (new tracks: false, 0).
        label = np.full(m, FALSE, dtype=np.int64)
        misses = np.zeros(m, dtype=np.int64)
        if len(self._ids):
            pos = np.minimum(np.searchsorted(self._ids, tids), len(self._ids) - 1)
            known = self._ids[pos] == tids
            label[known] = self._labels[pos[known]]
            misses[known] = self._misses[pos[known]]
        was_false = label == FALSE
        # Rule 3: the track selected a detection of its target.
        hit = ~was_false & np.any(sel == label[:, None], axis=1)
        # Rule 4: a missed scan; re-test (7.1) once the misses reach retest_after.
        missed = ~was_false & ~hit
        misses = np.where(missed, misses + 1, 0)
        own_pass = np.zeros(m, dtype=bool)
        if m and len(gids):
            g_order = np.argsort(gids)
            col = np.searchsorted(gids[g_order], label)
            col = np.minimum(col, len(gids) - 1)
            present = gids[g_order][col] == label
            own_pass = present & passes[np.arange(m), g_order[col]]
        relabel = was_false | (missed & (misses >= self.retest_after) & ~own_pass)
        # Rule 2 for false tracks, and the re-test outcome: nearest passing target or false.
        label = np.where(relabel, nearest, label)
        misses = np.where(relabel, 0, misses)
        keep = np.argsort(tids)
        self._ids, self._labels, self._misses = tids[keep], label[keep], misses[keep]
        return label

    def label_of(self, track_id: int) -> int:
        """Current label of ``track_id`` (``FALSE`` if unknown)."""
        i = np.searchsorted(self._ids, int(track_id))
        if i < len(self._ids) and self._ids[i] == int(track_id):
            return int(self._labels[i])
        return FALSE
