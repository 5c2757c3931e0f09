"""Sensor sites for ASTERIX data: a TOML file mapping SAC/SIC to a :class:`RadarSite`.

.. code-block:: toml

    [[radar]]
    sac = 20
    sic = 129
    lat = 41.300702   # degrees, WGS-84
    lon = 2.102058
    alt = 27.26       # metres above the WGS-84 ellipsoid
    # optional: any other RadarSite field, e.g.
    kind = "2d"       # 2d (default), 3d, cartesian or wgs84
    name = "Barcelona"
    sigma_range = 70.0        # m
    sigma_azimuth = 0.0012    # rad
    scan_period = 4.0         # s (otherwise from CAT034 I041 or estimated from the plots)
    p_detection = 0.95
    max_range = 460000.0      # m

The radar id of SAC ``s`` / SIC ``i`` is ``"{s}-{i}"`` (e.g. ``"20-129"``): decimal,
one key-safe chunk matching ``schemas.keys.ID_PATTERN``, the same in the reader, the
Zenoh keys and the MCAP topics. The ADS-B (CAT021) output of a SAC/SIC is a sensor of
its own, ``"{s}-{i}-adsb"`` (a multilateration system often sends its own ADS-B reports
under its SAC/SIC: LEBL's SAC 0 / SIC 107 sends CAT010 and CAT021); its table has
``adsb = true`` (kind ``wgs84`` and detection ``reports`` unless given).

Keys left out of a table are the :class:`RadarSite` defaults, except for sensors of
CAT010/CAT020/CAT021 reports, whose kind, detection and cycle the reader takes from
their reports when the table does not give them (:mod:`.report_batches`).
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from pydantic import ValidationError
from skyfuse.schemas import RadarSite

#: Keys a ``[[radar]]`` table may hold besides ``sac``/``sic``/``adsb``.
SITE_KEYS = tuple(k for k in RadarSite.model_fields if k != "radar_id")
REQUIRED_KEYS = ("sac", "sic", "lat", "lon", "alt")
ADSB_SUFFIX = "-adsb"
"""Radar-id suffix of the ADS-B (CAT021) output of a SAC/SIC."""


class SitesError(ValueError):
    """A sites file problem; the message names the file, table, key and value."""


def radar_id_for(sac: int, sic: int, adsb: bool = False) -> str:
    """The radar id of a SAC/SIC pair: ``"{sac}-{sic}"``, ``"{sac}-{sic}-adsb"`` for its
    ADS-B (CAT021) reports."""
    return f"{int(sac)}-{int(sic)}" + (ADSB_SUFFIX if adsb else "")


def sac_sic_of(radar_id: str) -> tuple[int, int]:
    """Inverse of :func:`radar_id_for` (the ``-adsb`` suffix dropped); ``ValueError`` for
    ids of another form."""
    try:
        a, b = radar_id.removesuffix(ADSB_SUFFIX).split("-")
        sac, sic = int(a), int(b)
    except ValueError:
        raise ValueError(
            f"radar id {radar_id!r} is not of the form 'SAC-SIC' (e.g. '25-11')"
        ) from None
    if not (0 <= sac <= 255 and 0 <= sic <= 255):
        raise ValueError(f"radar id {radar_id!r}: SAC and SIC must be in 0..255")
    return sac, sic


def parse_sites(doc: dict[str, Any], source: str = "<sites>") -> dict[str, RadarSite]:
    """Sites from an already-parsed TOML document (see :func:`load_sites`)."""
    unknown_top = sorted(set(doc) - {"radar"})
    if unknown_top:
        raise SitesError(
            f"{source}: unknown top-level key(s) {unknown_top}; radars go in [[radar]] tables"
        )
    tables = doc.get("radar", [])
    if not isinstance(tables, list):
        raise SitesError(f"{source}: 'radar' must be an array of tables: write [[radar]]")
    sites: dict[str, RadarSite] = {}
    for n, table in enumerate(tables, start=1):
        where = f"{source}: [[radar]] #{n}"
        if not isinstance(table, dict):
            raise SitesError(f"{where}: expected a table, got {table!r}")
        for key in REQUIRED_KEYS:
            if key not in table:
                raise SitesError(f"{where}: key {key!r} is missing (required: {REQUIRED_KEYS})")
        for key in ("sac", "sic"):
            value = table[key]
            if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value <= 255:
                raise SitesError(f"{where}: key {key!r} = {value!r}: must be an integer 0..255")
        where = f"{where} (sac={table['sac']}, sic={table['sic']})"
        unknown = sorted(set(table) - set(SITE_KEYS) - {"sac", "sic", "adsb"})
        if unknown:
            raise SitesError(
                f"{where}: unknown key(s) {unknown}; allowed: sac, sic, adsb, "
                f"{', '.join(SITE_KEYS)}"
            )
        adsb = table.get("adsb", False)
        if not isinstance(adsb, bool):
            raise SitesError(f"{where}: key 'adsb' = {adsb!r}: must be true or false")
        radar_id = radar_id_for(table["sac"], table["sic"], adsb)
        if radar_id in sites:
            raise SitesError(f"{where}: sensor {radar_id} is defined twice")
        fields = {k: v for k, v in table.items() if k not in ("sac", "sic", "adsb")}
        if adsb:
            fields.setdefault("kind", "wgs84")
            fields.setdefault("detection", "reports")
        try:
            sites[radar_id] = RadarSite(radar_id=radar_id, **fields)
        except ValidationError as exc:
            problems = []
            for err in exc.errors():
                key = ".".join(str(p) for p in err["loc"]) or "(table)"
                value = table.get(key, "<missing>") if err["loc"] else "<table>"
                problems.append(f"key {key!r} = {value!r}: {err['msg']}")
            raise SitesError(f"{where}: " + "; ".join(problems)) from None
    return sites


def load_sites(path: str | Path) -> dict[str, RadarSite]:
    """Read a sites TOML file: radar id (``"SAC-SIC"``) → :class:`RadarSite`.

    Raises :class:`SitesError` (a ``ValueError``) naming the table, key and value."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SitesError(f"{path}: sites file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise SitesError(f"{path}: not valid TOML: {exc}") from None
    return parse_sites(doc, str(path))
