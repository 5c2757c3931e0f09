"""Sites TOML: SAC/SIC → RadarSite, with errors naming table, key and value."""

from __future__ import annotations

import pytest
from skyfuse.services.asterix import SitesError, cat034, load_sites, radar_id_for, sac_sic_of
from skyfuse.services.asterix.reader import AsterixStreamDecoder
from skyfuse.services.asterix.writer import datablock

GOOD = """
[[radar]]
sac = 20
sic = 129
lat = 41.300702   # degrees, WGS-84
lon = 2.102058
alt = 27.26

[[radar]]
sac = 20
sic = 130
lat = 41.5
lon = 2.5
alt = 100.0
kind = "3d"
name = "second"
sigma_range = 70.0
sigma_azimuth = 0.0012
scan_period = 4.8
p_detection = 0.95
max_range = 460000.0
"""


def write(tmp_path, text: str):
    path = tmp_path / "sites.toml"
    path.write_text(text)
    return path


def test_load_good_file(tmp_path):
    sites = load_sites(write(tmp_path, GOOD))
    assert list(sites) == ["20-129", "20-130"]
    a, b = sites["20-129"], sites["20-130"]
    assert (a.lat, a.lon, a.alt, a.kind) == (41.300702, 2.102058, 27.26, "2d")
    assert (b.kind, b.name, b.sigma_range, b.scan_period, b.max_range) == (
        "3d",
        "second",
        70.0,
        4.8,
        460000.0,
    )
    assert "scan_period" not in a.model_fields_set and "scan_period" in b.model_fields_set


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ("sac = 1\nsic = 2\nlat = 1.0\nlon = 2.0", r"#1.*'alt' is missing"),
        ("sac = 1\nsic = 2\nlat = 95.0\nlon = 2.0\nalt = 0.0", r"sic=2\).*'lat' = 95.0"),
        ("sac = 300\nsic = 2\nlat = 1.0\nlon = 2.0\nalt = 0.0", r"'sac' = 300.*0\.\.255"),
        ('sac = "a"\nsic = 2\nlat = 1.0\nlon = 2.0\nalt = 0.0', r"'sac' = 'a'"),
        ("sac = 1\nsic = 2\nlat = 1.0\nlon = 2.0\nalt = 0.0\nrange = 5", r"unknown key.*'range'"),
        ('sac = 1\nsic = 2\nlat = 1.0\nlon = 2.0\nalt = 0.0\nkind = "4d"', r"'kind' = '4d'"),
    ],
)
def test_errors_name_table_key_and_value(tmp_path, table, message):
    with pytest.raises(SitesError, match=message):
        load_sites(write(tmp_path, "[[radar]]\n" + table + "\n"))


def test_duplicate_and_structural_errors(tmp_path):
    one = "[[radar]]\nsac = 1\nsic = 2\nlat = 1.0\nlon = 2.0\nalt = 0.0\n"
    with pytest.raises(SitesError, match=r"#2.*1-2 is defined twice"):
        load_sites(write(tmp_path, one + one))
    with pytest.raises(SitesError, match="not valid TOML"):
        load_sites(write(tmp_path, "[[radar]\n"))
    with pytest.raises(SitesError, match=r"\[\[radar\]\]"):
        load_sites(write(tmp_path, "radar = 3\n"))
    with pytest.raises(SitesError, match="not found"):
        load_sites(tmp_path / "missing.toml")


def test_radar_id_round_trip():
    assert radar_id_for(25, 201) == "25-201"
    assert sac_sic_of("25-201") == (25, 201)
    for bad in ("25_201", "25-256", "x-1", "1-2-3"):
        with pytest.raises(ValueError, match="SAC"):
            sac_sic_of(bad)


def test_sites_file_scan_period_overrides_cat034_only_when_given(tmp_path):
    sites = load_sites(write(tmp_path, GOOD))
    dec = AsterixStreamDecoder(sites=sites)
    for rid in ("20-129", "20-130"):  # North markers saying the period is 5.5 s
        sac, sic = sac_sic_of(rid)
        rec = cat034.encode_record(sac=sac, sic=sic, message_type=1, tod=100.0, period_s=5.5)
        dec.feed(datablock(34, [rec]), None)
    got, source = dec.current_sites()
    assert source == {"20-129": "cat034", "20-130": "sites"}
    assert got["20-129"].scan_period == 5.5 and got["20-130"].scan_period == 4.8
    assert got["20-129"].lat == sites["20-129"].lat  # the sites file keeps the position
