"""``skyfuse simulate``: run a named scenario offline (no network) and write the radar
sites, sector plot batches and ground truth to an MCAP recording on the same topics
the live sensors use."""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, Field, field_validator

from .config import ConfigError, add_model_arguments, build_config
from .progress import progress_bar

log = logging.getLogger(__name__)


class SimulateConfig(BaseModel):
    """Configuration of ``skyfuse simulate`` (TOML table ``[simulate]``)."""

    scenario: str = Field("regional", description="Scenario name (see --list)")
    seed: int = Field(1, ge=0, description="Random seed: the same seed gives the same file")
    duration: float | None = Field(None, gt=0, description="Duration in seconds (scenario default)")
    targets: int | None = Field(None, ge=0, description="Number of targets (scenario default)")
    param: list[str] = Field(
        default_factory=list, description="Scenario parameter overrides KEY=VALUE,KEY=VALUE"
    )
    out: Path = Field(Path("sim.mcap"), description="Output file")
    format: Literal["mcap", "asterix"] = Field(
        "mcap", description="Output format: mcap, or asterix (CAT048/CAT034 data blocks)"
    )
    progress: bool | None = Field(None, description="Show a progress bar (default: on a terminal)")

    @field_validator("param")
    @classmethod
    def _kv(cls, v: list[str]) -> list[str]:
        for item in v:
            if "=" not in item or not item.split("=", 1)[0].strip():
                raise ValueError(f"param {item!r} is not KEY=VALUE")
        return v


def parse_params(items: list[str]) -> dict[str, object]:
    """``["a=1", "b=x"]`` → ``{"a": 1, "b": "x"}`` with numbers and booleans parsed."""
    out: dict[str, object] = {}
    for item in items:
        key, value = (s.strip() for s in item.split("=", 1))
        try:
            out[key] = json.loads(value)
        except json.JSONDecodeError:
            out[key] = value
    return out


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate a scenario to an MCAP recording (offline)",
        description=__doc__,
    )
    p.add_argument("--config", type=Path, help="TOML file with a [simulate] table")
    p.add_argument("--list", action="store_true", help="list the scenarios and exit")
    add_model_arguments(p, SimulateConfig)
    p.set_defaults(func=run)


def simulate_to_mcap(cfg: SimulateConfig) -> dict:
    """Run the scenario and write the recording; return a summary dict."""
    from fusion.sim import Simulator, build_scenario

    from .recording import RecordingWriter

    try:
        scenario = build_scenario(
            cfg.scenario,
            seed=cfg.seed,
            duration=cfg.duration,
            targets=cfg.targets,
            **parse_params(cfg.param),
        )
    except ValueError as e:
        raise ConfigError(str(e)) from None
    sim = Simulator(scenario, seed=cfg.seed)
    metadata = {
        "command": "skyfuse simulate",
        "scenario": scenario.name,
        "seed": str(cfg.seed),
        "duration_s": str(scenario.duration),
        "targets": str(scenario.n_targets),
        "frame": scenario.frame.model_dump_json(),
        "params": json.dumps(scenario.params, default=str),
    }
    counts = {"site": 0, "plots": 0, "truth": 0}
    n_plots = 0
    t0 = time.perf_counter()
    cfg.out.parent.mkdir(parents=True, exist_ok=True)
    start_ns = scenario.start_time
    total_s = float(scenario.duration)
    with RecordingWriter(cfg.out, metadata=metadata) as writer:
        with progress_bar(f"simulate {scenario.name}", round(total_s), enabled=cfg.progress) as adv:
            shown = 0
            for ev in sim.run():
                writer.write(ev.topic, ev.message, ev.time)
                counts[ev.kind] += 1
                if ev.kind == "plots":
                    n_plots += len(ev.message)
                elapsed = int((ev.time - start_ns) / 1e9)
                if elapsed > shown:
                    adv(min(elapsed, round(total_s)) - shown)
                    shown = min(elapsed, round(total_s))
        messages = writer.messages
    wall = time.perf_counter() - t0
    return {
        "out": str(cfg.out),
        "scenario": scenario.name,
        "seed": cfg.seed,
        "duration_s": scenario.duration,
        "targets": scenario.n_targets,
        "radars": [s.radar_id for s in scenario.sites],
        "sites": counts["site"],
        "plot_batches": counts["plots"],
        "plots": n_plots,
        "truth_messages": counts["truth"],
        "messages": messages,
        "wall_s": round(wall, 3),
    }


def run(args: argparse.Namespace) -> int:
    if args.list:
        from fusion.sim import SCENARIOS

        for name, desc in SCENARIOS.items():
            print(f"{name:16s} {desc}")
        return 0
    section = "simulate" if args.config else None
    cfg = build_config(SimulateConfig, args, toml_path=args.config, section=section)
    if cfg.format != "mcap":
        raise ConfigError(f"format {cfg.format!r} is not available yet; use mcap")
    summary = simulate_to_mcap(cfg)
    log.info(
        "wrote %s: %s plots in %s batches from %s radars, %s truth messages (%.2f s)",
        summary["out"],
        summary.get("plots"),
        summary.get("plot_batches"),
        len(summary.get("radars", [])),
        summary.get("truth_messages"),
        summary.get("wall_s", 0),
    )
    json.dump(summary, sys.stdout)
    sys.stdout.write("\n")
    return 0
