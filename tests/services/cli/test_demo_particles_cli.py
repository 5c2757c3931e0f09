"""``skyfuse demo --tracker lmipf --particles N``: the flag parses, has the bounds and
default of ``TrackerConfig.particles`` (one spelling for one setting across commands), and
the fusion process's arguments give a TrackerConfig with that N (parsed by the real
``skyfuse fusion`` parser and configuration chain)."""

from __future__ import annotations

import pytest
from skyfuse.fusion.sim import build_scenario
from skyfuse.fusion.tracker import TrackerConfig
from skyfuse.services.cli import cmd_fusion
from skyfuse.services.cli.cmd_demo import fusion_arguments
from skyfuse.services.cli.main import build_parser, main
from skyfuse.services.evaluation.demo import DemoConfig
from skyfuse.services.runtime.config import build_config


def _fusion_config(demo_argv: list[str]) -> tuple[DemoConfig, TrackerConfig]:
    cfg = build_config(DemoConfig, build_parser("demo").parse_args(["demo", *demo_argv]))
    frame = build_scenario("regional", seed=1, duration=10.0, targets=1).frame
    argv = fusion_arguments(cfg, frame, ["--connect", "tcp/127.0.0.1:7447", "--no-multicast"])
    return cfg, cmd_fusion.tracker_config(build_parser("fusion").parse_args(argv))


def test_particles_reach_the_fusion_process_config():
    cfg, tc = _fusion_config(["--tracker", "lmipf", "--particles", "250"])
    assert (cfg.tracker, cfg.particles) == ("lmipf", 250)
    assert (tc.tracker, tc.particles) == ("lmipf", 250)


def test_default_is_the_tracker_default():
    cfg, tc = _fusion_config([])
    assert cfg.particles == TrackerConfig().particles == tc.particles == 1000
    assert tc.tracker == cfg.tracker == "lmits"


def test_demo_bounds_equal_the_tracker_bounds():
    demo, trk = DemoConfig.model_fields["particles"], TrackerConfig.model_fields["particles"]
    assert demo.default == trk.default and demo.description == trk.description
    assert [repr(m) for m in demo.metadata] == [repr(m) for m in trk.metadata]


@pytest.mark.parametrize("value", ["0", "2000000", "many"])
def test_bad_particles_are_a_usage_error(value, capsys):
    assert main(["demo", "--tracker", "lmipf", "--particles", value]) == 2
    assert "particles" in capsys.readouterr().err
