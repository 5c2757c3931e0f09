"""The one rule that places the system frame from the radar sites, used by the live fusion
service (:class:`skyfuse.services.fusion.service.FusionCore`) and by the offline runner
(:func:`skyfuse.services.evaluation.offline.run_offline`), so that the same recording
gives the same frame — and the same tracks — both ways.

Rule: unless the origin is configured, the frame is centred on the **spherical mean of
the sites known when the first plot batch of a radar with a known site is applied**.
Live, that is after the batch's reorder hold (``reorder_wait``), not at its receipt:
Zenoh runs each subscriber's callbacks on its own thread, so a site published before a
plot batch on another key can be delivered after it (seen: two of three sites 90 ms
late on a loaded machine, and a frame centred on one radar). Offline, it is at the first
plot batch in recording order. A replay publishes every site of the recording that
precedes its first plot batch before that batch, so both ways take the same sites, and
give the same tracks; a site recorded after the first plot batch is in the offline frame
never, in the live one if it is heard within that batch's hold. The spherical mean is
the direction of the mean of the sites' unit vectors (x = cos φ cos λ, y = cos φ sin λ,
z = sin φ; φ latitude, λ longitude), so that radars on both sides of the antimeridian get
a centre between them, not on the other side of the Earth. The origin height is 0 m
(stereographic: heights stay above the WGS-84 ellipsoid; NED: the tangent plane at the
ellipsoid). Frames: stereographic (PROJ ``+proj=sterea``) or a local tangent plane
(ENU state, NED a view of it) — see :class:`skyfuse.fusion.frames.SystemFrame`.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from skyfuse.schemas import FrameKind, FrameSpec, RadarSite


def sites_centre(sites: Iterable[RadarSite]) -> tuple[float, float] | None:
    """Spherical mean (lat, lon) of the sites, degrees; ``None`` without sites."""
    s = sorted(sites, key=lambda site: site.radar_id)
    if not s:
        return None
    if len(s) == 1:
        return float(s[0].lat), float(s[0].lon)
    lat = np.radians([site.lat for site in s])
    lon = np.radians([site.lon for site in s])
    v = np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)]).mean(1)
    norm = float(np.linalg.norm(v))
    if norm < 1e-9:  # antipodal sites: no meaningful centre, take the first by id
        return float(s[0].lat), float(s[0].lon)
    lat0 = float(np.degrees(np.arcsin(np.clip(v[2] / norm, -1.0, 1.0))))
    lon0 = float(np.degrees(np.arctan2(v[1], v[0])))
    return lat0, lon0


def frame_for_sites(
    sites: Iterable[RadarSite],
    kind: FrameKind | str | None = None,
    lat0: float | None = None,
    lon0: float | None = None,
    alt0: float = 0.0,
) -> FrameSpec | None:
    """The system frame: ``kind`` (default stereographic) at the configured origin
    (``lat0``/``lon0`` degrees, ``alt0`` m) when both are given, else at the spherical
    mean of ``sites`` (height 0 m); ``None`` when neither is available yet."""
    kind = FrameKind(kind) if kind is not None else FrameKind.STEREOGRAPHIC
    if lat0 is not None and lon0 is not None:
        return FrameSpec(kind=kind, lat0=lat0, lon0=lon0, alt0=alt0)
    centre = sites_centre(sites)
    if centre is None:
        return None
    return FrameSpec(kind=kind, lat0=centre[0], lon0=centre[1], alt0=0.0)
