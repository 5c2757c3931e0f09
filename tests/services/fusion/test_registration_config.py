"""The registration settings of ``skyfuse fusion``, ``track`` and ``eval``: defaults <
the ``[registration]`` TOML table < ``SKYFUSE_REGISTRATION_*`` < ``--registration`` /
``--registration-reference`` / ``--registration-max-reference-sigma``, with the same flags
on the three commands; and the link's correction: none for reference radars, zero
estimates, ``off`` and cartesian sensors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from service_support import make_site
from skyfuse.fusion.registration import RegistrationConfig
from skyfuse.fusion.tracker.measurements import MeasurementBatch, SectorCoverage
from skyfuse.schemas import RadarKind
from skyfuse.services.cli.main import build_parser
from skyfuse.services.fusion.registration_link import RegistrationLink, registration_config
from skyfuse.services.runtime.config import ConfigError


@pytest.mark.parametrize("command", [["fusion"], ["track", "r.mcap"], ["eval", "r.mcap"]])
def test_toml_env_and_flags_in_order(tmp_path, monkeypatch, command):
    toml = tmp_path / "f.toml"
    toml.write_text('[registration]\nmode = "frozen"\nreference = ["A"]\nprior_range_m = 100\n'
                    "max_reference_sigma = 60\n")  # fmt: skip
    parse = build_parser(command[0]).parse_args
    cfg = registration_config(parse(command), toml_path=toml)
    assert (cfg.mode, cfg.reference, cfg.prior_range_m) == ("frozen", ["A"], 100.0)
    assert cfg.max_reference_sigma == 60.0
    monkeypatch.setenv("SKYFUSE_REGISTRATION_PRIOR_RANGE_M", "50")
    args = parse([*command, "--registration", "off", "--registration-reference", "B,C",
                  "--registration-max-reference-sigma", "40"])  # fmt: skip
    cfg = registration_config(args, toml_path=toml)
    assert (cfg.mode, cfg.reference, cfg.prior_range_m) == ("off", ["B", "C"], 50.0)
    assert cfg.max_reference_sigma == 40.0
    assert registration_config(parse(command)).mode == "on"  # the default
    assert registration_config(parse(command)).max_reference_sigma is None
    with pytest.raises(SystemExit):
        parse([*command, "--registration", "maybe"])
    toml.write_text('[registration]\ncomponents = ["azimuth", "skew"]\n')
    with pytest.raises(ConfigError, match="components"):
        registration_config(parse(command), toml_path=toml)


def _batch(t_end: int) -> MeasurementBatch:
    cov = SectorCoverage(site=np.zeros(2), min_range=0.0, max_range=1e5, sector_start=0.0,
                         sector_width=1.0, time_start=t_end - 10**9, time_end=t_end)  # fmt: skip
    return MeasurementBatch(time_ns=t_end, radar_id="A", z=np.zeros((0, 2)),
                            R=np.zeros((0, 2, 2)), p_detection=0.9, coverage=cov)  # fmt: skip


def test_link_correction_and_time_shift():
    link = RegistrationLink(RegistrationConfig(reference=["A"], apply_sigma=0.0))
    a, b = make_site("A", 45.0, 20.0), make_site("B", 45.5, 20.5)
    assert link.correction(a) is None and link.correction(b) is None  # estimates are 0
    # give B an estimate as the filter would hold it (state in units of the prior σ)
    f = link.estimator.filter
    i = link.estimator.radar_ids.index("B")
    f.s[4 * i : 4 * i + 4] = np.array([0.2, 0.5, 0.0, 0.2])
    corr = link.correction(b)
    assert math.isclose(corr.azimuth, 0.2 * math.radians(0.5))
    assert math.isclose(corr.range, 150.0) and math.isclose(corr.time, 0.05)
    assert link.correction(a) is None  # the reference is never corrected
    mb = link.shift_times(_batch(10**18), corr)
    assert mb.time_ns == 10**18 - 50_000_000
    assert (mb.coverage.time_start, mb.coverage.time_end) == (
        10**18 - 10**9 - 50_000_000, 10**18 - 50_000_000)  # fmt: skip
    assert link.shift_times(_batch(7), None).time_ns == 7
    cart = make_site("B", 45.5, 20.5).model_copy(update={"kind": RadarKind.CARTESIAN})
    assert link.correction(cart) is None  # no polar bias model
    link.estimator.set_mode("off")
    assert link.correction(b) is None
    link.estimator.set_mode("frozen")
    assert link.correction(b) == corr


def test_link_applies_only_significant_components():
    """Default apply_sigma = 3: a component within 3σ of 0 is not applied (the prior σ is
    the filter's σ here, state in units of it), one beyond 3σ is."""
    link = RegistrationLink(RegistrationConfig(reference=["A"]))
    a, b = make_site("A", 45.0, 20.0), make_site("B", 45.5, 20.5)
    assert link.correction(a) is None and link.correction(b) is None  # both registered
    f = link.estimator.filter
    i = link.estimator.radar_ids.index("B")
    f.s[4 * i : 4 * i + 4] = np.array([3.5, 0.5, 0.0, 2.9])
    corr = link.correction(b)
    assert math.isclose(corr.azimuth, 3.5 * math.radians(0.5))
    assert corr.range == 0.0 and corr.time == 0.0
