"""Online sensor registration in the fusion pipeline (docs/concepts/registration.md): the two calls
:class:`~skyfuse.services.fusion.pipeline.TrackPipeline` makes per plot batch, the
configuration shared by ``skyfuse fusion``, ``skyfuse track`` and ``skyfuse eval FILE``,
and the published :class:`~skyfuse.schemas.RegistrationStatus`.

Per batch of radar r (method: :mod:`skyfuse.fusion.registration`, docs/concepts/registration.md):

1. :meth:`RegistrationLink.before` — the current estimate β̂_r is the correction of the
   conversion (``convert_plots(bias=…)``, sensor_bias eq. 2). The radar's clock is
   wrong by b_t for the sweep too, so the batch time and the sector's time_start/end are
   shifted by −b̂_t (ns) like the plot times.
2. :meth:`RegistrationLink.after` — the plots the tracker assigned to tracks that two or
   more sensors update feed the estimator (:func:`observe_tracker_output`); a report
   sensor's (ADS-B) only when it is a named reference (``--registration-reference
   ADSB``: its positions are the datum, every radar is estimated against them), and only
   its reports whose σ is within ``--registration-max-reference-sigma``.

The correction is ``None`` (the conversion untouched) while the estimate is exactly 0
(reference radars, a radar before its first common-target pair, ``off``) and for
cartesian and WGS-84 sensors (no polar bias model). With one radar, or radars without common
coverage, no pair ever forms, so registration is in effect off; it is therefore on by
default. Everything is a function of the batches in their order, so a live run and an
offline run of the same recording give the same estimates and the same tracks.
"""

from __future__ import annotations

import dataclasses

from pydantic import BaseModel, Field
from skyfuse.fusion.registration import (
    RegistrationConfig,
    RegistrationEstimator,
    RegistrationMode,
    observe_tracker_output,
)
from skyfuse.schemas import RadarKind, RegistrationStatus
from skyfuse.schemas.snapshot import entry, mapping
from skyfuse.services.runtime.config import add_model_arguments, build_config

REGISTRATION_SECTION = "registration"
"""The TOML table of :class:`RegistrationConfig`."""


class RegistrationLink:
    """The registration state of one pipeline, and the ``plots_near_radar`` count."""

    def __init__(self, config: RegistrationConfig | None = None) -> None:
        self.estimator = RegistrationEstimator(config or RegistrationConfig())
        self.plots_near_radar = 0
        self.pairs_used = 0
        self.time_ns = 0

    @property
    def mode(self) -> RegistrationMode:
        return self.estimator.mode

    def correction(self, site):
        """The SensorBias to remove from ``site``'s plots, or None (module docstring)."""
        polar = site.kind in (RadarKind.TWO_D, RadarKind.THREE_D)
        if not polar or self.mode is RegistrationMode.OFF:
            return None
        corr = self.estimator.correction(site.radar_id)
        return None if corr is None or corr.is_zero else corr

    @staticmethod
    def shift_times(mb, corr):
        """``mb`` (MeasurementBatch) with the batch and sweep times moved by −b̂_t."""
        if corr is None or not corr.time_ns:
            return mb
        dt = corr.time_ns
        cov = mb.coverage
        if cov is not None:
            cov = dataclasses.replace(
                cov, time_start=cov.time_start - dt, time_end=cov.time_end - dt
            )
        return dataclasses.replace(mb, time_ns=mb.time_ns - dt, coverage=cov)

    def after(self, out, converted, velocity_index) -> int:
        """Feed the estimator with the tracker output of ``converted``; count near-radar
        plots. Returns the pairs used."""
        self.plots_near_radar += converted.n_near_radar
        self.time_ns = max(self.time_ns, int(out.time_ns))
        n = observe_tracker_output(self.estimator, out, converted, velocity_index)
        self.pairs_used += n
        return n

    def to_snapshot(self) -> dict:
        """The estimator's snapshot and this link's counters."""
        return {
            "estimator": self.estimator.to_snapshot(),
            "plots_near_radar": self.plots_near_radar,
            "pairs_used": self.pairs_used,
            "time_ns": self.time_ns,
        }

    def from_snapshot(self, snap) -> None:
        """Hold :meth:`to_snapshot` (on a link just made with the same configuration)."""
        snap = mapping(snap, "registration")
        self.estimator.from_snapshot(snap.get("estimator"))
        self.plots_near_radar = entry(snap, "plots_near_radar", int)
        self.pairs_used = entry(snap, "pairs_used", int)
        self.time_ns = entry(snap, "time_ns", int)

    def status(self, fusion_id: str) -> RegistrationStatus:
        """The estimates with their σ, as published (schemas.registration)."""
        st = self.estimator.status()
        degrees = ("azimuth_deg", "azimuth_sigma_deg")  # the wire model is SI only
        radars = [{k: v for k, v in r.items() if k not in degrees} for r in st["radars"]]
        return RegistrationStatus(
            fusion_id=fusion_id,
            time=self.time_ns,
            mode=st["mode"],
            radars=radars,
            plots_waiting=st["plots_waiting"],
            plots_dropped=st["plots_dropped"],
            plots_not_finite=st["plots_not_finite"],
        )


def registration_config(args=None, *, toml_path=None) -> RegistrationConfig:
    """RegistrationConfig: defaults < TOML ``[registration]`` < ``SKYFUSE_REGISTRATION_*`` <
    the flags ``--registration MODE``, ``--registration-reference A,B`` and
    ``--registration-max-reference-sigma M``."""
    over = {}
    if args is not None:
        if getattr(args, "registration", None) is not None:
            over["mode"] = args.registration
        if getattr(args, "registration_reference", None) is not None:
            over["reference"] = args.registration_reference
        if getattr(args, "registration_max_reference_sigma", None) is not None:
            over["max_reference_sigma"] = args.registration_max_reference_sigma
    return build_config(
        RegistrationConfig,
        None,
        toml_path=toml_path,
        section=REGISTRATION_SECTION,
        env_prefix="SKYFUSE_REGISTRATION_",
        overrides=over,
    )


class RegistrationFlags(BaseModel):
    """The command-line flags of the registration (the rest of its settings: the
    ``[registration]`` TOML table, :class:`RegistrationConfig`)."""

    registration: RegistrationMode | None = Field(
        None,
        description="on: estimate and correct the radar biases; frozen: correct with the "
        "estimate reached; off (default: on; with one radar nothing is estimated)",
    )
    registration_reference: list[str] | None = Field(
        None,
        description="Reference sensors, bias fixed at 0: radars, or an ADS-B sensor to "
        "register every radar against its reports (default: the first radar seen)",
    )
    registration_max_reference_sigma: float | None = Field(
        None,
        gt=0,
        description="Use only the reports of a reference ADS-B (or multilateration) whose "
        "horizontal σ per axis is at most this many metres (default: all)",
    )


def add_registration_arguments(parser) -> None:
    """``--registration on|frozen|off``, ``--registration-reference A,B`` and
    ``--registration-max-reference-sigma M``."""
    g = parser.add_argument_group(
        "sensor registration",
        "Online estimation and correction of each radar's azimuth, range, range-gain and "
        "time biases from common targets (docs/concepts/registration.md); also the [registration] "
        "TOML table and SKYFUSE_REGISTRATION_<FIELD>",
    )
    add_model_arguments(g, RegistrationFlags)
