"""`skyfuse eval FILE.pcap --sites ...`: a real-data style evaluation scored by Mode-S."""

from __future__ import annotations

import json
import subprocess
import sys


def skyfuse(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "skyfuse.services.cli", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)


def test_eval_asterix_recording_reports_label_metrics(tmp_path):
    pcap = tmp_path / "ev.pcap"
    res = skyfuse("simulate", "--scenario", "regional", "--duration", "40", "--seed", "3",
                  "--format", "asterix", "--out", str(pcap))  # fmt: skip
    assert res.returncode == 0, res.stderr
    sites = f"{pcap}.sites.toml"
    out = tmp_path / "ev.json"
    res = skyfuse("eval", str(pcap), "--sites", sites, "--tracker", "lmits", "--json", str(out))
    assert res.returncode == 0, res.stderr[-2000:]
    metrics = json.loads(res.stdout.strip().splitlines()[-1])
    assert metrics["aircraft"] > 5
    assert 0.5 <= metrics["completeness"] <= 1.0
    labels = json.loads(out.read_text())["labels"]
    assert labels["kind"] == "mode_s" and labels["plots_labelled"] > 0
    assert {k: labels[k] for k in ("aircraft", "completeness")} == {
        k: metrics[k] for k in ("aircraft", "completeness")
    }
    res = skyfuse("eval", str(pcap), "--sites", str(tmp_path / "missing.toml"))
    assert res.returncode == 2 and "sites file not found" in res.stderr
