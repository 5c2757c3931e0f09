"""Differential test: the compiled-layout fast path decodes exactly what libasterix
decodes (the independent reference), on real records and on random bytes."""

from __future__ import annotations

from collections import Counter

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from service_support import SHARED_DATA
from skyfuse.services.asterix import cat034, cat048
from skyfuse.services.asterix.pcap import iter_file_datagrams, split_datablocks
from skyfuse.services.asterix.records import RecordError, iter_records

PCAP = SHARED_DATA / "cat_034_048.pcap"


def lib_first(module, data: bytes):
    """libasterix's decoding of the first record of ``data`` and its length, or None."""
    for rec in iter_records(module.SPEC, data):
        if isinstance(rec, RecordError):
            return None
        return module.decode_record(rec), len(rec.unparse().to_bytes())
    return None


def agree(module, data: bytes) -> None:
    fast = module.decode_fast(data, 0)
    lib = lib_first(module, data)
    assert (fast is None) == (lib is None), (data.hex(), fast, lib)
    if fast is not None:
        assert fast[0] == lib[0] and fast[1] == lib[1], (data.hex(), fast, lib)


@pytest.mark.skipif(not PCAP.exists(), reason="../shared/data sample absent")
def test_sample_records_agree():
    stats: Counter = Counter()
    seen = Counter()
    for dgram in iter_file_datagrams(PCAP, stats):
        for cat, data in split_datablocks(dgram.payload, stats):
            module = {48: cat048, 34: cat034}[cat]
            pos = 0
            while pos < len(data):
                agree(module, data[pos:])
                pos = module.decode_fast(data, pos)[1]
                seen[cat] += 1
    assert seen == {48: 128, 34: 34}


@st.composite
def cat048_records(draw) -> bytes:
    items = {
        "010": (("SAC", draw(st.integers(0, 255))), ("SIC", draw(st.integers(0, 255)))),
        "140": draw(st.integers(0, 2**24 - 1)),
    }
    if draw(st.booleans()):
        groups = [(draw(st.integers(0, 7)), draw(st.integers(0, 1)), 0,
                   draw(st.integers(0, 1)), 0, None)]  # TYP, SIM, RDP, SPI, RAB  # fmt: skip
        if draw(st.booleans()):
            groups.append((draw(st.integers(0, 1)), 0, 0, 0, 0, 0, None))
        items["020"] = tuple(groups)
    if draw(st.booleans()):
        items["040"] = (
            ("RHO", draw(st.integers(0, 65535))),
            ("THETA", draw(st.integers(0, 65535))),
        )
    if draw(st.booleans()):
        items["070"] = (
            draw(st.integers(0, 1)),
            draw(st.integers(0, 1)),
            draw(st.integers(0, 1)),
            0,
            ("MODE3A", draw(st.integers(0, 4095))),
        )
    if draw(st.booleans()):
        items["090"] = (
            draw(st.integers(0, 1)),
            draw(st.integers(0, 1)),
            ("FL", draw(st.integers(0, 2**14 - 1))),
        )
    if draw(st.booleans()):
        names = draw(st.sets(st.sampled_from(["SRL", "SRR", "SAM", "PRL", "PAM", "RPD", "APD"])))
        items["130"] = {n: draw(st.integers(0, 255)) for n in names}
    if draw(st.booleans()):
        items["220"] = draw(st.integers(0, 2**24 - 1))
    if draw(st.booleans()):
        items["240"] = draw(st.integers(0, 2**48 - 1))
    if draw(st.booleans()):
        items["250"] = [draw(st.integers(0, 2**64 - 1)) for _ in range(draw(st.integers(0, 3)))]
    if draw(st.booleans()):
        items["230"] = draw(st.integers(0, 2**16 - 1))
    if draw(st.booleans()):
        items["161"] = (0, ("TRN", draw(st.integers(0, 4095))))
    if draw(st.booleans()):
        items["030"] = [draw(st.integers(0, 127)) for _ in range(draw(st.integers(1, 3)))]
    return cat048.SPEC.cv_record.create(items).unparse().to_bytes()


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(cat048_records(), st.binary(max_size=4))
def test_random_valid_cat048_records_agree(record, tail):
    agree(cat048, record + tail)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(min_size=1, max_size=40))
def test_random_bytes_agree(data):
    agree(cat048, data)
    agree(cat034, data)


cat048_values = st.fixed_dictionaries(
    {
        "sac": st.integers(0, 255),
        "sic": st.integers(0, 255),
        "tod": st.floats(0, 86_400, exclude_max=True),
        "rho_nm": st.floats(0, 255.99),
        "theta_deg": st.floats(0, 360, exclude_max=True),
        "typ": st.integers(1, 7),
        "sim": st.booleans(),
        "flight_level": st.none() | st.floats(-2047, 2047),
        "mode_3a": st.none() | st.integers(0, 4095),
        "mode_s": st.none() | st.integers(0, 2**24 - 1),
        "amplitude_dbm": st.none() | st.floats(-150, 150),
    },
    optional={
        "spi": st.booleans(),
        "mode_3a_not_validated": st.booleans(),
        "mode_3a_garbled": st.booleans(),
        "mode_3a_smoothed": st.booleans(),
        "flight_level_not_validated": st.booleans(),
        "flight_level_garbled": st.booleans(),
        "flight_status": st.integers(0, 7),
        "callsign": st.from_regex(r"[A-Z0-9 ]{0,8}", fullmatch=True),
        "registers": st.lists(
            st.tuples(st.integers(0, 2**56 - 1), st.integers(0, 255)), max_size=4
        ),
    },
)


@settings(max_examples=200, deadline=None)
@given(cat048_values)
def test_cat048_encoder_matches_libasterix(values):
    data = cat048.encode_record(**values)
    assert data == cat048.build_record(**values).unparse().to_bytes()
    plot, end = cat048.decode_fast(data, 0)  # and decodes to what was encoded
    assert end == len(data)
    for key in ("spi", "mode_3a_not_validated", "mode_3a_garbled", "mode_3a_smoothed",
                "flight_level_not_validated", "flight_level_garbled"):  # fmt: skip
        code = "flight_level" if key.startswith("flight") else "mode_3a"
        carried = key == "spi" or values.get(code) is not None
        assert getattr(plot, key) == (carried and values.get(key, False)), key
    assert plot.flight_status == values.get("flight_status")
    assert plot.callsign == (values.get("callsign", "").rstrip() or None)
    assert plot.registers == tuple(values.get("registers", ()))


cat034_values = st.fixed_dictionaries(
    {
        "sac": st.integers(0, 255),
        "sic": st.integers(0, 255),
        "message_type": st.integers(1, 2),
        "tod": st.floats(0, 86_400, exclude_max=True),
        "sector_deg": st.none() | st.floats(0, 360, exclude_max=True),
        "period_s": st.none() | st.floats(0, 500),
        "position": st.none()
        | st.tuples(st.floats(-90, 90), st.floats(-180, 180), st.floats(-500, 9000)),
    }
)


@settings(max_examples=200, deadline=None)
@given(cat034_values)
def test_cat034_encoder_matches_libasterix(values):
    assert cat034.encode_record(**values) == cat034.build_record(**values).unparse().to_bytes()


@pytest.mark.skipif(not PCAP.exists(), reason="../shared/data sample absent")
def test_reader_gives_the_same_batches_with_and_without_the_fast_path():
    from skyfuse.services.asterix import read_asterix

    fast = read_asterix(PCAP, dedup=False)
    slow = read_asterix(PCAP, dedup=False, fast=False)
    assert [b.model_dump() for b in fast.batches] == [b.model_dump() for b in slow.batches]
    assert fast.stats == slow.stats
