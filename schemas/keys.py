"""The versioned Zenoh key space of skyfuse; the same names are the MCAP topics.

``@v1`` is a verbatim chunk: it only matches itself, so a future ``@v2`` key space
never mixes with this one.

=================================================  ======================  =================
key expression                                     payload                 direction
=================================================  ======================  =================
``skyfuse/@v1/radar/{id}/site``                    :class:`RadarSite`      sensor →
``skyfuse/@v1/radar/{id}/plots``                   :class:`PlotBatch`      sensor →
``skyfuse/@v1/radar/{id}/alive``                   liveliness token        sensor
``skyfuse/@v1/fusion/{id}/tracks``                 :class:`TrackBatch`     fusion →
``skyfuse/@v1/fusion/{id}/events``                 :class:`TrackEvent`     fusion →
``skyfuse/@v1/fusion/{id}/status``                 :class:`Status`         fusion →
``skyfuse/@v1/fusion/{id}/snapshot``               queryable → TrackBatch  fusion
``skyfuse/@v1/fusion/{id}/registration``           RegistrationStatus      fusion →
``skyfuse/@v1/fusion/{id}/state``                  snapshot blob (npz)     fusion → standby
``skyfuse/@v1/fusion/{id}/active/{inst}``          liveliness token        fusion (election)
``skyfuse/@v1/fusion/{id}/standby/{inst}/status``  :class:`Status`         standby →
``skyfuse/@v1/sim/truth``                          :class:`Truth`          simulator →
``skyfuse/@v1/service/{name}/status``              :class:`Status`         any service
``skyfuse/@v1/service/{name}/alive``               liveliness token        any service
=================================================  ======================  =================

``state`` is the active instance's whole tracker state (``services.fusion.state_codec``,
every ``snapshot_interval`` s) for a hot standby on another host; only the fusion
identity may publish or read it (``skyfuse certs`` policy). ``{inst}`` names one
instance of a fusion id (``{start ns}-{zenoh id}``): each standby reports its own Status
on its own key, never on the active one's ``status``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

PREFIX = "skyfuse/@v1"
ID_PATTERN = r"^[A-Za-z0-9_.\-]{1,64}$"
_ID_RE = re.compile(ID_PATTERN)

ALL = f"{PREFIX}/**"
ALL_PLOTS = f"{PREFIX}/radar/*/plots"
ALL_SITES = f"{PREFIX}/radar/*/site"
ALL_ALIVE = f"{PREFIX}/radar/*/alive"
SIM_TRUTH = f"{PREFIX}/sim/truth"


def check_id(value: str, what: str = "id") -> str:
    """Reject ids that are not a single safe key chunk (no '/', '*', '$', '@', '#', '?')."""
    if not isinstance(value, str) or not _ID_RE.match(value):
        raise ValueError(
            f"{what} {value!r} is not valid: use 1-64 characters from A-Z a-z 0-9 _ . -"
        )
    return value


def radar_site(radar_id: str) -> str:
    return f"{PREFIX}/radar/{check_id(radar_id, 'radar id')}/site"


def radar_plots(radar_id: str) -> str:
    return f"{PREFIX}/radar/{check_id(radar_id, 'radar id')}/plots"


def radar_alive(radar_id: str) -> str:
    return f"{PREFIX}/radar/{check_id(radar_id, 'radar id')}/alive"


def fusion_tracks(fusion_id: str) -> str:
    return f"{PREFIX}/fusion/{check_id(fusion_id, 'fusion id')}/tracks"


def fusion_events(fusion_id: str) -> str:
    return f"{PREFIX}/fusion/{check_id(fusion_id, 'fusion id')}/events"


def fusion_status(fusion_id: str) -> str:
    return f"{PREFIX}/fusion/{check_id(fusion_id, 'fusion id')}/status"


def fusion_snapshot(fusion_id: str) -> str:
    return f"{PREFIX}/fusion/{check_id(fusion_id, 'fusion id')}/snapshot"


def fusion_registration(fusion_id: str) -> str:
    """Online sensor-registration estimates (RegistrationStatus, docs/concepts/registration.md)."""
    return f"{PREFIX}/fusion/{check_id(fusion_id, 'fusion id')}/registration"


def fusion_state(fusion_id: str) -> str:
    """The active instance's state snapshot for its standbys (binary, docs/reliability.md §5)."""
    return f"{PREFIX}/fusion/{check_id(fusion_id, 'fusion id')}/state"


def fusion_standby_status(fusion_id: str, instance: str) -> str:
    """The Status of one standby instance of a fusion id."""
    fid, inst = check_id(fusion_id, "fusion id"), check_id(instance, "instance")
    return f"{PREFIX}/fusion/{fid}/standby/{inst}/status"


def service_alive(name: str) -> str:
    """Liveliness token of a running service (fusion, recorder, …)."""
    return f"{PREFIX}/service/{check_id(name, 'service name')}/alive"


def service_status(name: str) -> str:
    return f"{PREFIX}/service/{check_id(name, 'service name')}/status"


@dataclass(frozen=True)
class KeyInfo:
    """What a key names: ``kind`` is one of site, plots, alive, tracks, events,
    status, snapshot, registration, state, standby-status, truth, service-status;
    ``owner`` the
    radar/fusion/service id."""

    kind: str
    owner: str | None


_PATTERNS = [
    (re.compile(rf"^{re.escape(PREFIX)}/radar/([^/]+)/(site|plots|alive)$"), None),
    (
        re.compile(
            rf"^{re.escape(PREFIX)}/fusion/([^/]+)/"
            r"(tracks|events|status|snapshot|registration|state)$"
        ),
        None,
    ),
    (re.compile(rf"^{re.escape(PREFIX)}/fusion/([^/]+)/standby/[^/]+/status$"), "standby-status"),
    (re.compile(rf"^{re.escape(PREFIX)}/service/([^/]+)/status$"), "service-status"),
    (re.compile(rf"^{re.escape(PREFIX)}/service/([^/]+)/alive$"), "service-alive"),
]


def parse(key: str) -> KeyInfo:
    """Classify a concrete key; raise ``ValueError`` for keys outside the v1 key space."""
    key = str(key)
    if key == SIM_TRUTH:
        return KeyInfo("truth", None)
    for rx, fixed_kind in _PATTERNS:
        m = rx.match(key)
        if m:
            return KeyInfo(fixed_kind or m.group(2), m.group(1))
    raise ValueError(f"key {key!r} is not in the {PREFIX} key space")
