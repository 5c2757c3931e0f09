"""`skyfuse simulate` → MCAP → `skyfuse inspect`, as a user runs them (real processes)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest
from mcap.reader import make_reader
from skyfuse.schemas import keys

SKYFUSE = [sys.executable, "-m", "skyfuse.services.cli"]


def run(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([*SKYFUSE, *args], capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def regional(tmp_path_factory) -> tuple:
    out = tmp_path_factory.mktemp("sim") / "r.mcap"
    res = run(
        "simulate", "--scenario", "regional", "--duration", "40", "--seed", "1", "--out", str(out)
    )
    assert res.returncode == 0, res.stderr
    return out, json.loads(res.stdout)


def test_simulate_regional_and_inspect_json(regional):
    out, summary = regional
    assert summary["plots"] > 0 and len(summary["radars"]) >= 3
    res = run("inspect", str(out), "--json")
    assert res.returncode == 0, res.stderr
    info = json.loads(res.stdout)
    with_plots = [r for r in info["radars"] if r["plots"] > 0]
    assert len(with_plots) >= 3
    assert all(r["site"] is not None for r in info["radars"])
    assert info["targets"] > 0 and info["truth_messages"] > 0
    assert keys.SIM_TRUTH in info["topics"]
    assert info["plots"] == summary["plots"]
    assert info["rejected"] == {} and not info["truncated"]
    assert 35 <= info["duration_s"] <= 41
    assert info["metadata"]["skyfuse"]["scenario"] == "regional"


def test_plain_reader_counts_every_message(regional):
    out, summary = regional
    with open(out, "rb") as f:
        stats = make_reader(f).get_summary().statistics
    n_plot_msgs = sum(n for cid, n in stats.channel_message_counts.items())
    assert n_plot_msgs == summary["messages"]


def test_same_seed_same_file_content(tmp_path):
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    for p in (a, b):
        assert (
            run("simulate", "--scenario", "thesis-mtt-5", "--seed", "7", "--out", str(p)).returncode
            == 0
        )
    ia = json.loads(run("inspect", str(a), "--json").stdout)
    ib = json.loads(run("inspect", str(b), "--json").stdout)
    for k in ("plots", "topics", "targets", "duration_s"):
        assert ia[k] == ib[k]


def test_bad_arguments_are_clear_errors(tmp_path):
    res = run("simulate", "--scenario", "nope", "--out", str(tmp_path / "x.mcap"))
    assert res.returncode == 2 and "nope" in res.stderr
    res = run("simulate", "--seed", "-3", "--out", str(tmp_path / "x.mcap"))
    assert res.returncode == 2 and "seed" in res.stderr
    res = run("simulate", "--param", "novalue", "--out", str(tmp_path / "x.mcap"))
    assert res.returncode == 2 and "KEY=VALUE" in res.stderr
    res = run("inspect", str(tmp_path / "missing.mcap"))
    assert res.returncode == 1 and "no such file" in res.stderr


@pytest.mark.skipif(shutil.which("pymcap-cli") is None, reason="pymcap-cli not installed")
def test_simulated_file_passes_doctor(tmp_path):
    out = tmp_path / "s.mcap"
    assert run("simulate", "--scenario", "thesis-stt", "--out", str(out)).returncode == 0
    res = subprocess.run(
        ["pymcap-cli", "doctor", str(out)], capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 0, res.stdout


def test_simulate_asterix_reads_back_same_plots(tmp_path):
    from skyfuse.services.asterix.reader import read_asterix
    from skyfuse.services.asterix.sites import load_sites

    out = tmp_path / "sim.pcap"
    res = run(
        "simulate",
        "--scenario",
        "regional",
        "--duration",
        "30",
        "--seed",
        "4",
        "--format",
        "asterix",
        "--out",
        str(out),
    )
    assert res.returncode == 0, res.stderr
    summary = json.loads(res.stdout)
    sites = load_sites(summary["sites_file"])
    assert len(sites) == len(summary["radars"]) >= 3
    back = read_asterix(out, sites=sites)
    assert sum(len(b) for b in back.batches) == summary["plots"]
    assert set(back.radars) == set(sites)


def test_simulate_asterix_refuses_cartesian_scenarios(tmp_path):
    res = run(
        "simulate",
        "--scenario",
        "thesis-stt",
        "--format",
        "asterix",
        "--out",
        str(tmp_path / "x.ast"),
    )
    assert res.returncode == 2 and "cartesian" in res.stderr
