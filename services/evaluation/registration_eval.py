"""Scoring the online sensor registration of an offline run against simulation truth
as an observer of :func:`~skyfuse.services.evaluation.offline.run_offline`.

:class:`RegistrationObserver` reads the simulated radars' systematic errors from the
recording's ``Truth.radar_bias`` (truth is used only here, to score) and

* samples the pipeline's estimates (``TrackPipeline.registration``) every ``every_s``
  seconds of recording time: the estimate ± σ of each radar against its truth, over time;
* at the end gives, per radar and component (azimuth, range, range gain, time), the
  estimate, σ, truth, error, z = error/σ and relative error |error|/|truth|, with the
  issue's acceptance tests (within 20 % of the truth, or within 2σ);
* counts duplicate confirmed tracks per aircraft from the samples of a
  :class:`~skyfuse.services.evaluation.observers.TruthObserver` (the targets in coverage
  and the latest confirmed tracks predicted to each Truth time, plane x east, y north,
  m): targets and tracks are assigned one to one (Hungarian, scipy
  ``linear_sum_assignment``) within ``radius``; a confirmed track within ``radius`` of a
  target that is not assigned is a duplicate. Duplicates per aircraft = duplicates /
  assigned target samples over the second half of the run (after acquisition).

The reference radars' truth is their own bias: an estimate is relative to the
references, so a biased reference shows as errors of the others.
"""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.frames.sensor_bias import BIAS_COMPONENTS
from skyfuse.schemas import Truth
from skyfuse.services.evaluation.numbers import json_number
from skyfuse.services.evaluation.offline import Observer, Step

_SCALE = {"azimuth": np.degrees(1.0), "range": 1.0, "range_gain": 1e6, "time": 1e3}
_UNIT = {"azimuth": "deg", "range": "m", "range_gain": "ppm", "time": "ms"}


def duplicate_counts(truth_pos: np.ndarray, track_pos: np.ndarray, radius: float):
    """(duplicates, assigned targets) at one instant: targets (n, 2) and confirmed
    tracks (k, 2) in m, one-to-one assignment within ``radius`` m (module docstring)."""
    from scipy.optimize import linear_sum_assignment

    if not len(truth_pos) or not len(track_pos):
        return 0, 0
    d = np.linalg.norm(track_pos[:, None, :] - truth_pos[None, :, :], axis=-1)
    r, c = linear_sum_assignment(np.where(d <= radius, d, 1e12))
    ok = d[r, c] <= radius
    near = (d <= radius).any(axis=1)
    return int(near.sum() - ok.sum()), int(ok.sum())


class RegistrationObserver(Observer):
    """Bias estimates against truth over time, and duplicates (module docstring);
    summary key ``registration_vs_truth`` (absent when the recording has no radar
    biases in its truth and no estimator ran)."""

    def __init__(self, truth_observer=None, every_s: float = 60.0, radius: float = 2000.0):
        self.truth_obs = truth_observer
        self.every_ns = int(every_s * 1e9)
        self.radius = radius
        self.truth: dict[str, np.ndarray] = {}
        self.pipeline = None
        self.t0: int | None = None
        self.next_ns: int | None = None
        self.series: list[dict] = []

    def on_step(self, step: Step) -> None:
        self.pipeline = step.pipeline

    def _registration(self):
        return getattr(self.pipeline, "registration", None)

    def on_truth(self, truth: Truth) -> None:
        for b in truth.radar_bias:
            self.truth[b.radar_id] = np.array([b.azimuth, b.range, b.range_gain, b.time])
        self.t0 = truth.time if self.t0 is None else self.t0
        reg = self._registration()
        if reg is None or (self.next_ns is not None and truth.time < self.next_ns):
            return
        self.next_ns = truth.time + self.every_ns
        row = {"t_s": json_number((truth.time - self.t0) * 1e-9, 1), "radars": {}}
        for e in reg.estimator.estimates():
            row["radars"][e.radar_id] = {
                f"{c}_{_UNIT[c]}": [json_number(v * _SCALE[c], 4), json_number(s * _SCALE[c], 4)]
                for c, v, s in zip(BIAS_COMPONENTS, e.bias.vector(), e.sigma)
            }
        self.series.append(row)

    def _final(self, reg) -> list[dict]:
        out = []
        for e in reg.estimator.estimates():
            truth = self.truth.get(e.radar_id, np.zeros(4))
            err = e.bias.vector() - truth
            row = {"radar_id": e.radar_id, "reference": e.reference, "pairs_used": e.pairs_used}
            for i, c in enumerate(BIAS_COMPONENTS):
                k, sig = _SCALE[c], e.sigma[i]
                z = err[i] / sig if sig > 0 else None
                rel = abs(err[i]) / abs(truth[i]) if truth[i] else None
                row[c] = {
                    "unit": _UNIT[c],
                    "estimate": json_number(e.bias.vector()[i] * k, 4),
                    "sigma": json_number(sig * k, 4),
                    "truth": json_number(truth[i] * k, 4),
                    "error": json_number(err[i] * k, 4),
                    "z": json_number(z, 2) if z is not None else None,
                    "relative_error": json_number(rel, 3) if rel is not None else None,
                    "within_20pct_or_2sigma": bool(
                        e.reference or (rel is not None and rel <= 0.2) or abs(err[i]) <= 2 * sig
                    ),
                }
            out.append(row)
        return out

    def duplicates(self) -> dict | None:
        """Duplicate confirmed tracks per aircraft over the second half of the run."""
        samples = getattr(self.truth_obs, "samples", None)
        if not samples:
            return None
        dup = matched = 0
        for _, pos, _, est, _ in samples[len(samples) // 2 :]:
            d, m = duplicate_counts(pos, est, self.radius)
            dup, matched = dup + d, matched + m
        return {
            "radius_m": self.radius,
            "duplicates": dup,
            "assigned_target_samples": matched,
            "duplicates_per_aircraft": json_number(dup / matched, 4) if matched else None,
        }

    def summary(self) -> dict:
        reg = self._registration()
        if not self.truth and reg is None:
            return {}
        out = {
            "truth": {
                rid: {c: json_number(v[i] * _SCALE[c], 4) for i, c in enumerate(BIAS_COMPONENTS)}
                for rid, v in sorted(self.truth.items())
            },
            "duplicates": self.duplicates(),
        }
        if reg is not None:
            out["mode"] = reg.mode.value
            out["final"] = self._final(reg)
            out["series"] = self.series
        return {"registration_vs_truth": out}
