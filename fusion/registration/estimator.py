"""``RegistrationEstimator``: online estimation of every radar's systematic errors from
the targets two or more radars see, and the correction the plot conversion applies.

One call per converted batch after the tracker step (:meth:`observe_plots`, or
:func:`fusion.registration.tracker_link.observe_tracker_output` straight from a
``TrackerOutput``); the next batch of a radar is converted with
``convert_plots(..., bias=estimator.correction(radar_id))``. Method: pairs of plots of one
track from two radars (:mod:`.common_target`), a Kalman / recursive-least-squares
filter on the stacked bias vectors with reference radars fixed at zero
(:mod:`.bias_filter`). No truth is used anywhere.

Modes (:class:`RegistrationMode`): ``on`` estimates and corrects, ``frozen`` corrects
with the estimate reached, ``off`` does neither (``correction`` returns None).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skyfuse.fusion.frames.sensor_bias import BIAS_COMPONENTS, SensorBias
from skyfuse.schemas.snapshot import SnapshotError, check_version, entry, mapping, strings

from .bias_filter import BiasFilter
from .common_target import PairBuffer, PlotColumns
from .config import RegistrationConfig, RegistrationMode

MAX_RADARS = 63
"""Bound on the radars of one estimator (the tracker's radar mask has 63 bits)."""


@dataclass(frozen=True)
class BiasEstimate:
    """One radar's estimate: ``bias`` (SensorBias, SI), ``sigma`` (4,) standard deviations
    (rad, m, 1, s; 0 where fixed), whether it is a reference, pairs used / rejected."""

    radar_id: str
    reference: bool
    bias: SensorBias
    sigma: np.ndarray
    pairs_used: int
    pairs_rejected: int

    def as_dict(self) -> dict:
        """JSON-ready: values and σ per component (azimuth also in degrees)."""
        v = self.bias.vector()
        out = {"radar_id": self.radar_id, "reference": self.reference,
               "pairs_used": self.pairs_used, "pairs_rejected": self.pairs_rejected}  # fmt: skip
        for name, val, sig in zip(BIAS_COMPONENTS, v, self.sigma):
            out[name] = float(val)
            out[f"{name}_sigma"] = float(sig)
        out["azimuth_deg"] = float(np.degrees(v[0]))
        out["azimuth_sigma_deg"] = float(np.degrees(self.sigma[0]))
        return out


class RegistrationEstimator:
    """Online registration of a radar network (see the module docstring)."""

    def __init__(self, config: RegistrationConfig | None = None) -> None:
        self.cfg = cfg = config or RegistrationConfig()
        self.filter = BiasFilter(cfg.prior_sigma(), cfg.estimated_mask(), cfg.p_gate)
        self.pairs = PairBuffer(cfg.max_pair_dt, cfg.q, cfg.capacity)
        self.radar_ids: list[str] = []
        self._t_last: int | None = None
        self.skipped = 0
        self.reference_excluded = 0

    @property
    def mode(self) -> RegistrationMode:
        return self.cfg.mode

    def set_mode(self, mode: RegistrationMode | str) -> None:
        """Switch on / frozen / off at run time (the estimate is kept)."""
        self.cfg = self.cfg.model_copy(update={"mode": RegistrationMode(mode)})

    def radar_index(self, radar_id: str) -> int:
        """The radar's index, registering it on first sight (reference when it is in
        ``config.reference``, or when that list is empty and it is the first radar)."""
        if radar_id not in self.radar_ids:
            if len(self.radar_ids) >= MAX_RADARS:
                raise ValueError(f"radar {radar_id!r}: at most {MAX_RADARS} radars")
            ref = self.cfg.reference
            is_ref = radar_id in ref if ref else not self.radar_ids
            self.radar_ids.append(radar_id)
            self.filter.add_radar(is_ref)
        return self.radar_ids.index(radar_id)

    def is_reference(self, radar_id: str) -> bool:
        """``radar_id`` is a named reference (a report sensor enters the registration only
        as one: it has no bias model of its own)."""
        return radar_id in self.cfg.reference

    def reference_quality(self, R: np.ndarray) -> np.ndarray:
        """(k,) bool: the reports of a reference report sensor good enough to use, those
        whose horizontal σ per axis √(tr R_xy / 2) (R (k, ≥2, ≥2) m² in the frame) is at
        most ``max_reference_sigma`` (all when it is None); the others are counted in
        ``reference_excluded``."""
        limit = self.cfg.max_reference_sigma
        if limit is None:
            return np.ones(len(R), bool)
        ok = 0.5 * (R[:, 0, 0] + R[:, 1, 1]) <= limit**2
        self.reference_excluded += int((~ok).sum())
        return ok

    def correction(self, radar_id: str) -> SensorBias | None:
        """The correction to pass to ``convert_plots(bias=…)``; None when ``off``."""
        if self.mode is RegistrationMode.OFF:
            return None
        i = self.radar_index(radar_id)
        b = self.filter.bias(i)
        # a component statistically indistinguishable from 0 is not applied: the noise
        # of an early or unobservable estimate (e.g. a time offset) must not move plots
        significant = np.abs(b) > self.cfg.apply_sigma * self.filter.sigma(i)
        return SensorBias.from_vector(np.where(significant, b, 0.0))

    def observe_plots(
        self,
        radar_id: str,
        track_ids: np.ndarray,
        time_ns: np.ndarray,
        z: np.ndarray,
        R: np.ndarray,
        dz_dpolar: np.ndarray,
        slant_range: np.ndarray,
        velocity: np.ndarray,
        Pvv: np.ndarray,
        applied: SensorBias | None,
    ) -> int:
        """Plots of ``radar_id`` assigned to tracks (arrays over k plots): track ids,
        corrected times ns, horizontal positions z (k, 2) m and covariances R (k, 2, 2),
        ∂z/∂(D, ψ) (k, 2, 2), corrected slant ranges (k,) m, track velocities (k, 2) m/s
        and their covariances (k, 2, 2); ``applied`` the correction used in their
        conversion. Rows with a non-finite value are skipped and counted. Returns the
        number of pairs that updated the estimate."""
        if self.mode is not RegistrationMode.ON:
            return 0
        k = len(track_ids)
        r = self.radar_index(radar_id)
        H = np.empty((k, 2, 4))
        H[:, :, 0] = dz_dpolar[:, :2, 1]  # ∂z/∂ψ
        H[:, :, 1] = dz_dpolar[:, :2, 0]  # ∂z/∂D
        H[:, :, 2] = dz_dpolar[:, :2, 0] * np.asarray(slant_range)[:, None]  # D ∂z/∂D
        H[:, :, 3] = -velocity[:, :2]  # a clock offset: p(t − b_t) ≈ p(t) − v b_t
        beta = np.zeros(4) if applied is None else applied.vector()
        finite = (
            np.isfinite(z[:, :2]).all(1) & np.isfinite(R[:, :2, :2]).all((1, 2))
            & np.isfinite(H).all((1, 2)) & np.isfinite(velocity[:, :2]).all(1)
            & np.isfinite(Pvv[:, :2, :2]).all((1, 2)) & np.isfinite(np.asarray(time_ns, float))
        )  # fmt: skip
        self.skipped += int(k - finite.sum())
        cols = PlotColumns(
            np.asarray(track_ids, np.int64), np.full(k, r, np.int64),
            np.asarray(time_ns, np.int64), z[:, :2], R[:, :2, :2], H,
            np.broadcast_to(beta, (k, 4)).copy(), velocity[:, :2], Pvv[:, :2, :2],
        ).take(np.flatnonzero(finite))  # fmt: skip
        self._drift(int(np.max(cols.time)) if len(cols) else None)
        return self.filter.update(self.pairs.add(cols))

    def _drift(self, t_ns: int | None) -> None:
        if t_ns is None:
            return
        if self._t_last is not None and t_ns > self._t_last and self.cfg.drift_per_hour > 0:
            hours = (t_ns - self._t_last) * 1e-9 / 3600.0
            self.filter.drift(self.cfg.drift_per_hour**2 * hours)
        self._t_last = t_ns if self._t_last is None else max(self._t_last, t_ns)

    def estimates(self) -> list[BiasEstimate]:
        """Every radar's current estimate with its uncertainty."""
        f = self.filter
        out = []
        for i, rid in enumerate(self.radar_ids):
            b = SensorBias.from_vector(f.bias(i))
            used, rej = int(f.pairs_used[i]), int(f.pairs_rejected[i])
            out.append(BiasEstimate(rid, f.reference[i], b, f.sigma(i), used, rej))
        return out

    def status(self) -> dict:
        """JSON-ready summary for a service Status / a registration key."""
        return {
            "mode": self.mode.value,
            "radars": [e.as_dict() for e in self.estimates()],
            "plots_waiting": len(self.pairs.store),
            "plots_dropped": self.pairs.dropped,
            "plots_not_finite": self.skipped,
            "reference_excluded": self.reference_excluded,
        }

    # --- snapshots -----------------------------------------------------------------------
    SNAPSHOT_VERSION = 2  # 2: max_reference_sigma, reference_excluded

    def to_snapshot(self) -> dict:
        """The estimator's state by name: the version, the configuration that produced it
        (its ``mode`` as switched at run time), the radars, the filter's estimate, the
        plots awaiting a partner and the counters."""
        return {
            "version": self.SNAPSHOT_VERSION,
            "config": self.cfg.model_dump(mode="json"),
            "radar_ids": list(self.radar_ids),
            "t_last": self._t_last,
            "skipped": self.skipped,
            "reference_excluded": self.reference_excluded,
            "filter": self.filter.to_snapshot(),
            "pairs": self.pairs.to_snapshot(),
        }

    def from_snapshot(self, snap) -> None:
        """Hold the state of :meth:`to_snapshot`, on an estimator just made with the same
        configuration but perhaps another mode (the snapshot's mode is taken); a
        :class:`~skyfuse.schemas.snapshot.SnapshotError` otherwise (discard the estimator)."""
        snap = check_version(snap, "registration", self.SNAPSHOT_VERSION)
        config = mapping(snap.get("config"), "registration configuration")
        mine = self.cfg.model_dump(mode="json")
        if {**config, "mode": None} != {**mine, "mode": None}:
            raise SnapshotError("the registration configuration differs from the snapshot's")
        try:
            mode = RegistrationMode(config.get("mode"))
        except ValueError:
            raise SnapshotError(f"registration mode {config.get('mode')!r}") from None
        radar_ids = strings(snap, "radar_ids")
        t_last = snap.get("t_last")
        if type(t_last) not in (int, type(None)):
            raise SnapshotError("t_last: not integer ns")
        self.filter.from_snapshot(mapping(snap.get("filter"), "registration filter"))
        if self.filter.n_radars != len(radar_ids) or len(radar_ids) > MAX_RADARS:
            raise SnapshotError(f"{len(radar_ids)} radars, a filter of {self.filter.n_radars}")
        self.pairs.from_snapshot(mapping(snap.get("pairs"), "registration pairs"))
        radars = self.pairs.store.radar
        if len(radars) and (radars.min() < 0 or radars.max() >= len(radar_ids)):
            raise SnapshotError("registration pairs of radars beyond the radar list")
        self.set_mode(mode)
        self.radar_ids, self._t_last = list(radar_ids), t_last
        self.skipped = entry(snap, "skipped", int)
        self.reference_excluded = entry(snap, "reference_excluded", int)
