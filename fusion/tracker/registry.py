"""The registry of tracker parts: names → association parts, tracker kinds and motion
densities. ``TrackerConfig.tracker`` / ``motion`` (and so the CLI's choices and help,
and the evaluation's tracker list) are derived from it, so a new association or density
is one new module plus one ``register_*`` call (at the end of this module for the parts
skyfuse ships; anywhere before the ``TrackerConfig`` is made for others, e.g. a test).

* associations: ``single`` (IPDA/ITS, [thesis] 5.16-5.18), ``lm`` (LM-IPDA/LM-ITS,
  6.12-6.22), ``joint`` (JIPDA/JITS, 6.1-6.8), ``gnn`` (:mod:`.associators`);
* tracker kinds: an association plus whether the Singer N-scan memory is used (ITS
  families) or the density is one Gaussian per track / one IMM per track (IPDA families);
  a kind may bring its own density, which replaces the motion's: ``ipf`` / ``lmipf``
  (particle clouds, :class:`.density.particles.ParticleDensity`, [LM-IPF], over the
  ``single`` / ``lm`` associations);
* motions: ``cv`` (constant velocity, :class:`.density.gaussian_mixture.
  GaussianMixtureDensity`), ``imm-cv-ct`` and ``imm-cv-singer``
  (:class:`.density.imm_mixture.IMMMixtureDensity`, an IMM inside every component); the
  filters of [MZD] and [Dikić]: ``singer``, ``imm-pcwpa``, ``imm-cv-singer-ct``
  (:mod:`.density.source_motions`); for airport surfaces ``imm-surface`` (CV, stopped
  and tight-turn modes, :mod:`.density.surface_motion`).

A density factory is ``factory(config) -> TrackDensity`` (:mod:`.density.base`: it
declares its own track-store columns, takes part in snapshots and says how it treats late
plots, so nothing else needs to know it); ``warm_up`` (optional) loads its compiled
kernels (:func:`warm_up_parts`, used by :func:`fusion.tracker.kernel_warmup.warm_up`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from . import associators as assoc
from .density.gaussian_mixture import GaussianMixtureDensity
from .density.imm_mixture import IMMMixtureDensity, imm_density
from .density.particles import ParticleDensity
from .density.source_motions import imm_cv_singer_ct_density, imm_pcwpa_density, singer_density
from .density.surface_motion import imm_surface_density
from .density.surface_motion import warm_up as surface_warm_up

ASSOCIATIONS: dict[str, Callable] = {}


@dataclass(frozen=True)
class TrackerKindSpec:
    """A tracker kind: its association part, whether it keeps Singer N-scan memory, a
    one-line description for help texts, and its own density factory (None: the
    motion's) with its warm-up."""

    association: str
    memory: bool
    description: str
    density: Callable | None = None
    warm_up: Callable | None = None


@dataclass(frozen=True)
class MotionSpec:
    """A motion density: ``factory(config) -> TrackDensity``, a description and the
    density's warm-up (None: nothing compiled of its own)."""

    factory: Callable
    description: str
    warm_up: Callable | None = None


TRACKERS: dict[str, TrackerKindSpec] = {}
MOTIONS: dict[str, MotionSpec] = {}


def register_association(name: str, fn: Callable) -> None:
    ASSOCIATIONS[name] = fn


def register_tracker(
    name: str,
    association: str,
    memory: bool,
    description: str,
    density: Callable | None = None,
    warm_up: Callable | None = None,
) -> None:
    """``density``: ``factory(config) -> TrackDensity`` of a kind that replaces the motion
    density (None: the configured motion's)."""
    if association not in ASSOCIATIONS:
        raise ValueError(f"tracker {name!r}: association {association!r} is not registered")
    TRACKERS[name] = TrackerKindSpec(association, memory, description, density, warm_up)


def register_motion(
    name: str, factory: Callable, description: str, warm_up: Callable | None = None
) -> None:
    MOTIONS[name] = MotionSpec(factory, description, warm_up)


def make_density(cfg):
    """The track density of a configuration: the tracker kind's own, else the motion's."""
    own = TRACKERS[cfg.tracker].density
    return own(cfg) if own is not None else MOTIONS[cfg.motion].factory(cfg)


def warm_up_parts() -> None:
    """Call the warm-up of every registered density once."""
    done = set()
    for spec in (*TRACKERS.values(), *MOTIONS.values()):
        if spec.warm_up is not None and spec.warm_up not in done:
            spec.warm_up()
            done.add(spec.warm_up)


def own_density_kinds() -> tuple[str, ...]:
    """Tracker kinds that bring their own density (motion must stay ``cv``)."""
    return tuple(k for k, v in TRACKERS.items() if v.density is not None)


def tracker_help() -> str:
    """'gnn (…), ipda (…), …' for help texts."""
    return ", ".join(f"{k} ({v.description})" for k, v in TRACKERS.items())


def motion_help() -> str:
    return ", ".join(f"{k} ({v.description})" for k, v in MOTIONS.items())


def single_gaussian_kinds() -> tuple[str, ...]:
    """Tracker kinds without Singer memory (depth fixed at 0)."""
    return tuple(k for k, v in TRACKERS.items() if not v.memory)


def _imm(second: str) -> Callable:
    return lambda cfg: imm_density(cfg, second)


register_association("single", assoc.associate_single)
register_association("lm", assoc.associate_lm)
register_association("joint", assoc.associate_joint)
register_association("gnn", assoc.associate_gnn)

_particles = ParticleDensity.from_config
register_tracker("gnn", "gnn", False, "global nearest neighbour with existence")
register_tracker("ipda", "single", False, "IPDA")
register_tracker("its", "single", True, "ITS, Singer N-scan memory")
register_tracker("lmipda", "lm", False, "LM-IPDA")
register_tracker("lmits", "lm", True, "LM-ITS")
register_tracker("jipda", "joint", False, "JIPDA")
register_tracker("jits", "joint", True, "JITS")
register_tracker("ipf", "single", False, "IPF, particle clouds", _particles)
register_tracker("lmipf", "lm", False, "LM-IPF, particle clouds", _particles)

_gm, _imm_warm = GaussianMixtureDensity, IMMMixtureDensity.warm_up
register_motion("cv", _gm.from_config, "constant velocity", _gm.warm_up)
register_motion("imm-cv-ct", _imm("ct"), "IMM of CV and coordinated turn", _imm_warm)
register_motion("imm-cv-singer", _imm("singer"), "IMM of CV and Singer", _imm_warm)
register_motion("singer", singer_density, "Singer KF ([MZD])", _imm_warm)
register_motion(
    "imm-pcwpa", imm_pcwpa_density, "IMM of two PCWPA, σ = g/2 and 2g ([MZD])", _imm_warm
)
register_motion(
    "imm-cv-singer-ct",
    imm_cv_singer_ct_density,
    "IMM of CV, Singer and coordinated turn ([Dikić]; 3x3 imm_tpm)",
    _imm_warm,
)
register_motion(
    "imm-surface",
    imm_surface_density,
    "IMM of CV, stopped (damped velocity) and tight turn, for airport surfaces",
    surface_warm_up,
)
