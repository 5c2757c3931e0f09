"""The registry of tracker parts: names → association parts, tracker kinds and motion
densities. ``TrackerConfig.tracker`` / ``motion`` (and so the CLI's choices and help,
and the evaluation's tracker list) are derived from it, so a new association or density
is one new module plus one ``register_*`` call here.

* associations: ``single`` (IPDA/ITS), ``lm`` (LM-IPDA/LM-ITS), ``joint`` (JIPDA/JITS),
  ``gnn`` (:mod:`fusion.tracker.associators`);
* tracker kinds: an association plus whether the Singer N-scan memory is used (ITS
  families) or the density is one Gaussian per track / one IMM per track (IPDA families);
  a kind may bring its own density, which replaces the motion's: ``ipf`` / ``lmipf``
  (particle clouds, :class:`fusion.particles.density.ParticleDensity`, spec 02 §6 and
  spec 04 A.2, over the ``single`` / ``lm`` associations);
* motions: ``cv`` (constant velocity, :class:`GaussianMixtureDensity`), ``imm-cv-ct``
  and ``imm-cv-singer`` (:class:`IMMMixtureDensity`, spec 01 §5 inside every component);
  the filters of [MZD] and [Dikić]: ``singer``, ``imm-pcwpa``, ``imm-cv-singer-ct``
  (:mod:`fusion.tracker.density.source_motions`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from . import associators as assoc

ASSOCIATIONS: dict[str, Callable] = {}


@dataclass(frozen=True)
class TrackerKindSpec:
    """A tracker kind: its association part, whether it keeps Singer N-scan memory, and a
    one-line description for help texts."""

    association: str
    memory: bool
    description: str
    density: Callable | None = None


@dataclass(frozen=True)
class MotionSpec:
    """A motion density: ``factory(config) -> TrackDensity`` and a description."""

    factory: Callable
    description: str


TRACKERS: dict[str, TrackerKindSpec] = {}
MOTIONS: dict[str, MotionSpec] = {}


def register_association(name: str, fn: Callable) -> None:
    ASSOCIATIONS[name] = fn


def register_tracker(
    name: str, association: str, memory: bool, description: str, density: Callable | None = None
) -> None:
    """``density``: ``factory(config) -> TrackDensity`` of a kind that replaces the motion
    density (None: the configured motion's)."""
    if association not in ASSOCIATIONS:
        raise ValueError(f"tracker {name!r}: association {association!r} is not registered")
    TRACKERS[name] = TrackerKindSpec(association, memory, description, density)


def register_motion(name: str, factory: Callable, description: str) -> None:
    MOTIONS[name] = MotionSpec(factory, description)


def make_density(cfg):
    """The track density of a configuration: the tracker kind's own, else the motion's."""
    own = TRACKERS[cfg.tracker].density
    return own(cfg) if own is not None else MOTIONS[cfg.motion].factory(cfg)


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


def _cv_density(cfg):
    from skyfuse.fusion.models.cv import ConstantVelocity

    from .density.gaussian_mixture import GaussianMixtureDensity

    model = ConstantVelocity(q=cfg.q, ndim=cfg.ndim, q_vertical=cfg.q_vertical)
    return GaussianMixtureDensity(model, cfg.memory_depth, cfg.prune_threshold, cfg.max_components)


def _imm_density(second: str):
    def factory(cfg):
        from .density.imm_mixture import imm_density

        return imm_density(cfg, second)

    return factory


def _source_motion(name: str):
    def factory(cfg):
        from .density import source_motions

        return getattr(source_motions, name)(cfg)

    return factory


def _particle_density(cfg):
    from skyfuse.fusion.particles.density import ParticleDensity  # lazy: no import cycle

    return ParticleDensity.from_config(cfg)


register_association("single", assoc.associate_single)
register_association("lm", assoc.associate_lm)
register_association("joint", assoc.associate_joint)
register_association("gnn", assoc.associate_gnn)

register_tracker("gnn", "gnn", False, "global nearest neighbour with existence")
register_tracker("ipda", "single", False, "IPDA")
register_tracker("its", "single", True, "ITS, Singer N-scan memory")
register_tracker("lmipda", "lm", False, "LM-IPDA")
register_tracker("lmits", "lm", True, "LM-ITS")
register_tracker("jipda", "joint", False, "JIPDA")
register_tracker("jits", "joint", True, "JITS")
register_tracker("ipf", "single", False, "IPF, particle clouds", _particle_density)
register_tracker("lmipf", "lm", False, "LM-IPF, particle clouds", _particle_density)

register_motion("cv", _cv_density, "constant velocity")
register_motion("imm-cv-ct", _imm_density("ct"), "IMM of CV and coordinated turn")
register_motion("imm-cv-singer", _imm_density("singer"), "IMM of CV and Singer")
register_motion("singer", _source_motion("singer_density"), "Singer KF ([MZD])")
register_motion(
    "imm-pcwpa", _source_motion("imm_pcwpa_density"), "IMM of two PCWPA, σ = g/2 and 2g ([MZD])"
)
register_motion(
    "imm-cv-singer-ct",
    _source_motion("imm_cv_singer_ct_density"),
    "IMM of CV, Singer and coordinated turn ([Dikić]; 3x3 imm_tpm)",
)
