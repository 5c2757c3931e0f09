"""``skyfuse eval FILE.mcap``: a simulated recording through one tracker, scored with its
plot labels (label metrics) and Truth messages (GOSPA)."""

from __future__ import annotations

import json

import pytest
from skyfuse.services.cli.main import main


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "m5.mcap"
    assert main(["simulate", "--scenario", "thesis-mtt-5", "--seed", "2", "--out", str(path),
                 "--no-progress"]) == 0  # fmt: skip
    return path


def test_eval_recording_scores_labels_and_truth(recording, tmp_path, capsys):
    out = tmp_path / "r.json"
    # the thesis's settings: its constant-velocity model with q = 0.75 (the IMM default of
    # the service is tuned for aircraft)
    code = main(["eval", str(recording), "--tracker", "lmits", "--motion", "cv", "--depth", "3",
                 "--q", "0.75", "--json", str(out)])  # fmt: skip
    assert code == 0
    d = json.loads(out.read_text())
    assert d["labels"] == "target_id" and d["batches"] == 40
    lm = d["label_metrics"]
    # 5 targets crossing without clutter: every one gets a confirmed track, none is false
    assert lm["aircraft"] == 5 and lm["completeness"] == 1.0 and lm["false_tracks"] == 0
    assert lm["confirmed_tracks"] >= 5 and lm["mean_id_changes"] >= 0
    g = d["gospa"]
    # one sample per Truth message after the first batch; GOSPA within [0, c·(n/2)^(1/p)]
    assert 39 <= g["samples"] <= 41
    assert 0 < g["mean_m"] <= 500.0 * (5 / 2) ** 0.5
    # before the first confirmation all 5 targets are missed
    assert g["missed_targets_mean"] > 0.5
    assert d["config"]["tracker"] == "lmits" and d["config"]["q"] == 0.75
    assert '"completeness": 1.0' in capsys.readouterr().out


def test_eval_recording_missing_file_is_a_clear_error(tmp_path, capsys):
    assert main(["eval", str(tmp_path / "nope.mcap"), "--tracker", "its"]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_eval_recording_with_mode_s_labels_only(tmp_path, capsys):
    """A 'real' recording: plots carry Mode-S addresses (one per target, none on clutter)
    and neither target_id nor Truth; the label metrics come from the addresses."""
    from skyfuse.fusion.sim import Simulator, build_scenario
    from skyfuse.services.recording.mcap_io import RecordingWriter

    sim = Simulator(build_scenario("thesis-mtt-5", seed=2, clutter_density=2e-6))
    path = tmp_path / "real.mcap"
    with RecordingWriter(path) as w:
        for ev in sim.run(truth=False):
            msg = ev.message
            if ev.kind == "plots":
                tid = msg.target_id
                msg = msg.model_copy(
                    update={
                        "target_id": None,
                        "mode_s": [None if t < 0 else 0xA00000 + t for t in tid],
                    }
                )
            w.write(ev.topic, msg, ev.time)
    out = tmp_path / "r.json"
    assert main(["eval", str(path), "--tracker", "its", "--depth", "2", "--q", "0.75",
                 "--json", str(out)]) == 0  # fmt: skip
    d = json.loads(out.read_text())
    assert d["labels"] == "mode_s" and "gospa" not in d
    lm = d["label_metrics"]
    assert lm["aircraft"] == 5 and lm["completeness"] == 1.0
    assert lm["confirmed_tracks"] >= 5 and lm["false_tracks"] <= 1
