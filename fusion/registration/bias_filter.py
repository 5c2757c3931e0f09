"""Recursive estimation of the radars' bias vectors from common-target residuals.

The state is the stacked bias vector β = (β_1, …, β_n) of the n radars, β_r =
(b_ψ, b_D, g, b_t) (:mod:`fusion.frames.sensor_bias`), with the reference radars' β fixed
at 0 (absolute registration needs a datum: a radar surveyed and trusted, or a set of
them, as in ARTAS). The measurement of each pair of plots of one target from radars a
and b is linear in β (:mod:`fusion.registration.common_target` eq. 2):

    y_k = H_{a,k} β_a − H_{b,k} β_b + w_k,   w_k ~ N(0, W_k)                        (1)

With a Gaussian prior β ~ N(0, P_0) and biases constant (or a random walk of variance
Q Δt), the Kalman filter for this static state is recursive least squares: its estimate
is the maximum a-posteriori / linearised maximum-likelihood estimate of the exact-ML
registration of Zhou, Leung & Yip ("An exact maximum likelihood registration algorithm
for data fusion", IEEE Trans. Signal Processing 45(6), 1997) and Okello & Ristic
("Maximum likelihood registration for multiple dissimilar sensors", IEEE TAES 39(3),
2003), computed recursively over the pairs instead of in one batch — the "Kalman
filter registration" used by operational multi-radar trackers. One batch of pairs is one
update in information form (Bar-Shalom, Li & Kirubarajan 2001, §7.2, eq. 7.2.1-3):

    Λ⁺ = Λ + Σ_k H_kᵀ W_k⁻¹ H_k,   η⁺ = η + Σ_k H_kᵀ W_k⁻¹ y_k,   β̂ = (Λ⁺)⁻¹ η⁺       (2)

Before the update every pair is gated on its normalised innovation
ν_kᵀ (H_k P H_kᵀ + W_k)⁻¹ ν_k ≤ χ²_2(p_gate) (wrong associations, manoeuvres). The 2 × 2
inverses (of the innovation covariance and of W_k) are closed forms; the gate and the
update are one compiled call (:mod:`.bias_filter_kernel`). The
state is kept in units of the prior σ (s = β/σ_0, P_0 = I) so that radians, metres,
ppm and seconds are conditioned alike.
"""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.association.gating import gate_threshold
from skyfuse.schemas.snapshot import SnapshotError, array_field, entry

from .bias_filter_kernel import gate_and_update
from .common_target import ResidualPairs


class BiasFilter:
    """Kalman / recursive-least-squares filter on the stacked bias vectors."""

    def __init__(self, prior_sigma: np.ndarray, estimated: np.ndarray, p_gate: float) -> None:
        self.sigma0 = np.asarray(prior_sigma, float).reshape(4)
        self.estimated = np.asarray(estimated, bool).reshape(4)
        self.gate = gate_threshold(p_gate, 2)
        self.reference: list[bool] = []
        self.s = np.zeros(0)  # normalised state, 4 per radar
        self.P = np.zeros((0, 0))
        self.pairs_used = np.zeros(0, np.int64)
        self.pairs_rejected = np.zeros(0, np.int64)

    @property
    def n_radars(self) -> int:
        return len(self.reference)

    def add_radar(self, reference: bool) -> int:
        """Register a radar; returns its index. Reference radars have no free state."""
        self.reference.append(bool(reference))
        n = 4 * self.n_radars
        P = np.zeros((n, n))
        P[: n - 4, : n - 4] = self.P
        P[n - 4 :, n - 4 :] = np.diag(self._free(len(self.reference) - 1).astype(float))
        self.s, self.P = np.r_[self.s, np.zeros(4)], P
        self.pairs_used = np.r_[self.pairs_used, 0]
        self.pairs_rejected = np.r_[self.pairs_rejected, 0]
        return self.n_radars - 1

    def _free(self, r: int) -> np.ndarray:
        return self.estimated & (not self.reference[r])

    def drift(self, variance_fraction: float) -> None:
        """Random walk: add ``variance_fraction`` × prior variance to the free states."""
        if self.n_radars:
            free = self._free_rows().reshape(-1)
            self.P[np.diag_indices_from(self.P)] += variance_fraction * free

    def bias(self, r: int) -> np.ndarray:
        """Estimate of radar r's bias vector (rad, m, 1, s)."""
        return self.s[4 * r : 4 * r + 4] * self.sigma0

    def sigma(self, r: int) -> np.ndarray:
        """Standard deviations of radar r's estimate (0 for fixed components)."""
        return np.sqrt(np.maximum(np.diag(self.P)[4 * r : 4 * r + 4], 0.0)) * self.sigma0

    def covariance(self, r: int) -> np.ndarray:
        """(4, 4) covariance of radar r's estimate in SI units."""
        sl = slice(4 * r, 4 * r + 4)
        return self.P[sl, sl] * np.outer(self.sigma0, self.sigma0)

    def _free_rows(self) -> np.ndarray:
        """(n, 4) bool: the estimated components of the non-reference radars."""
        return self.estimated[None, :] & ~np.asarray(self.reference, bool)[:, None]

    def update(self, pairs: ResidualPairs) -> int:
        """Gate and apply one batch of pairs (eq. 2, :mod:`.bias_filter_kernel`); returns
        the number used."""
        if len(pairs) == 0 or self.n_radars == 0:
            return 0
        c = np.ascontiguousarray
        return gate_and_update(
            self.s, self.P, c(self._free_rows().reshape(-1)), self.sigma0,
            c(pairs.y, float), c(pairs.W, float), c(pairs.HA, float), c(pairs.HB, float),
            c(pairs.a, np.int64), c(pairs.b, np.int64), float(self.gate),
            self.pairs_used, self.pairs_rejected,
        )  # fmt: skip

    def to_snapshot(self) -> dict:
        """The estimate: the radars' reference flags, the normalised state s (4n,) and
        covariance P (4n, 4n), the pairs used and rejected per radar (n,); the prior and
        the gate are the configuration's."""
        return {"reference": list(self.reference), "s": self.s, "P": self.P,
                "pairs_used": self.pairs_used, "pairs_rejected": self.pairs_rejected}  # fmt: skip

    def from_snapshot(self, snap: dict) -> None:
        """Hold the estimate of :meth:`to_snapshot` (checked first: nothing changes on a
        :class:`~skyfuse.schemas.snapshot.SnapshotError`)."""
        reference = entry(snap, "reference", list)
        if not all(type(r) is bool for r in reference):
            raise SnapshotError("reference: not a list of booleans")
        n = len(reference)
        s = array_field(snap, "s", np.float64, (4 * n,))
        P = array_field(snap, "P", np.float64, (4 * n, 4 * n))
        used = array_field(snap, "pairs_used", np.int64, (n,))
        rejected = array_field(snap, "pairs_rejected", np.int64, (n,))
        self.reference, self.s, self.P = list(reference), s, P
        self.pairs_used, self.pairs_rejected = used, rejected
