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

from pydantic import Field
from skyfuse.services.runtime.config import ConfigError, add_model_arguments, build_config
from skyfuse.services.runtime.progress import progress_bar
from skyfuse.services.sensors.scenario_config import ScenarioSelection

log = logging.getLogger(__name__)


class SimulateConfig(ScenarioSelection):
    """Configuration of ``skyfuse simulate`` (TOML table ``[simulate]``)."""

    out: Path = Field(Path("sim.mcap"), description="Output file")
    format: Literal["mcap", "asterix"] = Field(
        "mcap",
        description="Output format: mcap, or asterix (CAT048/CAT034; .pcap name: UDP in pcap, "
        "else raw data blocks; sites in <out>.sites.toml)",
    )
    asterix_sac: int = Field(0, ge=0, le=255, description="SAC of simulated radars in ASTERIX")
    progress: bool | None = Field(None, description="Show a progress bar (default: on a terminal)")


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


def _build(cfg: SimulateConfig):
    """The scenario and its simulator, or a ConfigError naming the bad parameter."""
    from skyfuse.fusion.sim import Simulator

    scenario = cfg.build_scenario()
    return scenario, Simulator(scenario, seed=cfg.seed)


def simulate_to_mcap(cfg: SimulateConfig) -> dict:
    """Run the scenario and write the recording; return a summary dict."""
    from skyfuse.services.recording.mcap_io import RecordingWriter

    scenario, sim = _build(cfg)
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


def asterix_sac_sic(radar_ids: list[str], sac: int) -> dict[str, tuple[int, int]]:
    """SAC/SIC for each simulated radar: ids already of the form ``SAC-SIC`` keep theirs,
    the others get ``sac`` and SIC 1, 2, … in order."""
    from skyfuse.services.asterix.sites import sac_sic_of

    out: dict[str, tuple[int, int]] = {}
    used: set[tuple[int, int]] = set()
    for rid in radar_ids:
        try:
            out[rid] = sac_sic_of(rid)
            used.add(out[rid])
        except ValueError:
            pass
    sic = 1
    for rid in radar_ids:
        if rid in out:
            continue
        while (sac, sic) in used:
            sic += 1
        out[rid] = (sac, sic)
        used.add((sac, sic))
    return out


def simulate_to_asterix(cfg: SimulateConfig) -> dict:
    """Write the scenario's plots as ASTERIX CAT048 with CAT034 service messages: a raw
    ``.ast`` file (concatenated data blocks) or, for a ``.pcap`` name, UDP datagrams in a
    pcap; plus ``<out>.sites.toml`` mapping SAC/SIC to the simulated sites."""
    import tomli_w
    from skyfuse.services.asterix.pcap import build_pcap
    from skyfuse.services.asterix.writer import AsterixPlotWriter

    scenario, sim = _build(cfg)
    other = [s.radar_id for s in scenario.sites if s.kind.value in ("cartesian", "wgs84")]
    if other:
        raise ConfigError(
            f"scenario {scenario.name!r} has cartesian or WGS-84 sensors ({', '.join(other)}): "
            "the simulator writes ASTERIX CAT048 polar plots only; use --format mcap"
        )
    sites = {s.radar_id: s for s in scenario.sites}
    sac_sic = asterix_sac_sic(list(sites), cfg.asterix_sac)
    writer = AsterixPlotWriter(sites, sac_sic=sac_sic, simulated=True)
    datagrams: list[tuple[int, bytes]] = []
    n_plots = n_batches = 0
    t0 = time.perf_counter()
    for ev in sim.run(truth=False):
        if ev.kind != "plots":
            continue
        n_batches += 1
        n_plots += len(ev.message)
        datagrams.extend((ev.time, block) for block in writer.encode_batch(ev.message))
    cfg.out.parent.mkdir(parents=True, exist_ok=True)
    if cfg.out.suffix.lower() == ".pcap":
        cfg.out.write_bytes(build_pcap(datagrams))
    else:
        cfg.out.write_bytes(b"".join(block for _, block in datagrams))
    sites_path = cfg.out.with_name(cfg.out.name + ".sites.toml")
    tables = []
    for rid, site in sites.items():
        sac, sic = sac_sic[rid]
        fields = site.model_dump(mode="json", exclude={"radar_id"}, exclude_none=True)
        fields["name"] = fields.get("name") or rid
        tables.append({"sac": sac, "sic": sic, **fields})
    sites_path.write_text(
        "# Sites of the simulated radars (skyfuse simulate --format asterix)\n"
        + tomli_w.dumps({"radar": tables})
    )
    return {
        "out": str(cfg.out),
        "sites_file": str(sites_path),
        "scenario": scenario.name,
        "seed": cfg.seed,
        "duration_s": scenario.duration,
        "targets": scenario.n_targets,
        "radars": [f"{rid} -> {sac}-{sic}" for rid, (sac, sic) in sac_sic.items()],
        "plot_batches": n_batches,
        "plots": n_plots,
        "datagrams": len(datagrams),
        "not_carried": dict(writer.stats),
        "wall_s": round(time.perf_counter() - t0, 3),
    }


def run(args: argparse.Namespace) -> int:
    if args.list:
        from skyfuse.fusion.sim import SCENARIOS

        for name, desc in SCENARIOS.items():
            print(f"{name:16s} {desc}")
        return 0
    section = "simulate" if args.config else None
    cfg = build_config(SimulateConfig, args, toml_path=args.config, section=section)
    summary = simulate_to_mcap(cfg) if cfg.format == "mcap" else simulate_to_asterix(cfg)
    log.info(
        "wrote %s: %s plots in %s batches from %s radars (%.2f s)",
        summary["out"],
        summary["plots"],
        summary["plot_batches"],
        len(summary["radars"]),
        summary["wall_s"],
    )
    json.dump(summary, sys.stdout)
    sys.stdout.write("\n")
    return 0
