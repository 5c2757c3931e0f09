"""What a new user meets first: ``--version``, the installed sample recording, and files
or situations that must fail with a message instead of a traceback or a silent exit 0
(replay of a non-MCAP file or with nobody listening, inspect/track of a non-recording),
and one flag spelling per setting across the commands."""

from __future__ import annotations

import argparse
import json
import logging
import threading
import tomllib

import pytest
from service_support import ROOT, peer, wait_for
from skyfuse.schemas import Truth, keys
from skyfuse.services.cli.main import build_parser, main
from skyfuse.services.recording.mcap_io import RecordingWriter, iter_recording
from skyfuse.services.recording.sample import sample_recording
from skyfuse.services.runtime.transport import Inbox, free_port, loopback_endpoint, open_session

REGIONAL = ("--scenario", "regional", "--seed", "4", "--duration", "12", "--targets", "3")


@pytest.fixture
def not_mcap(tmp_path):
    path = tmp_path / "hostname"
    path.write_bytes(b"vm\n")
    return path


def test_version_is_the_project_version(capsys):
    expected = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out.strip() == f"skyfuse {expected}"


def test_sample_recording_is_the_shipped_file():
    path = sample_recording()
    assert path.read_bytes() == (ROOT / "recordings" / "regional-demo.mcap").read_bytes()


def test_replay_of_a_non_mcap_file_says_so(not_mcap, capsys):
    assert main(["replay", str(not_mcap), "--fast"]) == 2
    err = capsys.readouterr().err
    assert "not an MCAP recording" in err and "b'vm\\n'" in err
    assert main(["replay", "--fast"]) == 2  # neither FILE nor --sample
    assert "FILE or --sample" in capsys.readouterr().err


def test_replay_without_plot_batches_fails(tmp_path, caplog):
    path = tmp_path / "truth-only.mcap"
    with RecordingWriter(path) as w:
        w.write(keys.SIM_TRUTH, Truth(time=1), 1)
    with caplog.at_level(logging.ERROR):
        assert main(["replay", str(path), "--fast"]) == 1
    assert "no plot batches to replay" in caplog.text


def test_replay_with_no_subscriber_fails_and_with_one_succeeds(simulated_recording, caplog):
    rec = simulated_recording(*REGIONAL)
    n = sum(1 for r in iter_recording(rec, decode=False) if r.topic.endswith("/plots"))
    argv = ["replay", str(rec), "--fast", "--no-multicast"]
    with caplog.at_level(logging.ERROR):
        assert main([*argv, "--wait-subscriber", "0.5", "--linger", "0"]) == 1
    assert "no subscriber for skyfuse/@v1/radar/*/plots" in caplog.text
    ep = loopback_endpoint(free_port())
    with open_session(peer(listen=ep)) as s:
        inbox = Inbox()
        inbox.subscribe(s, keys.ALL_PLOTS, "plots")
        rc = main([*argv, "--connect", ep, "--wait-subscriber", "10"])
        got: list = []
        assert wait_for(lambda: got.extend(inbox.drain(100_000)) or len(got) >= n, 10.0)
        inbox.close()
    assert rc == 0 and len(got) == n > 10


def test_inspect_of_a_non_mcap_file_is_an_error_not_a_traceback(not_mcap, tmp_path, capsys):
    assert main(["inspect", str(not_mcap)]) == 1
    assert "not an MCAP recording" in capsys.readouterr().err
    out = tmp_path / "i.json"
    assert main(["inspect", str(sample_recording()), "--json", str(out)]) == 0
    assert json.loads(out.read_text())["file"] == str(sample_recording())


def test_track_says_what_is_wrong_with_the_file(not_mcap, tmp_path, caplog, capsys):
    with caplog.at_level(logging.ERROR):
        assert main(["track", str(not_mcap), "--out", str(tmp_path / "t.mcap")]) == 1
    assert "not a recording: neither MCAP" in caplog.text and "b'vm\\n'" in caplog.text
    assert main(["track", str(tmp_path / "missing.mcap")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_track_json_switch_prints_the_whole_summary(simulated_recording, tmp_path, capsys):
    rec = simulated_recording(*REGIONAL)
    argv = ["track", str(rec), "--out", str(tmp_path / "t.mcap"), "--no-progress"]
    assert main([*argv, "--frame-kind", "ned", "--depth", "1", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["frame"]["kind"] == "ned" and s["config"]["depth"] == 1 and "labels" in s


def _options(parser: argparse.ArgumentParser) -> dict[str, dict[str, argparse.Action]]:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {
        name: {o: a for a in p._actions for o in a.option_strings}
        for name, p in sub.choices.items()
    }


def test_one_flag_spelling_per_setting_across_commands():
    opts = _options(build_parser())
    # the tracker: the same TrackerConfig flags wherever a tracker runs
    for cmd in ("track", "eval", "fusion"):
        assert {"--tracker", "--depth", "--q", "--p-gate"} <= set(opts[cmd]), cmd
    assert all("--tracker-set" not in o for o in opts.values())
    # the system frame: --frame-kind everywhere, never --frame
    assert all("--frame" not in o for o in opts.values())
    assert {"--frame-kind"} <= set(opts["track"]) & set(opts["fusion"])
    # JSON output: --json [FILE] (FILE optional: stdout) in the commands that write a summary
    for cmd in ("track", "eval", "demo", "inspect"):
        assert opts[cmd]["--json"].nargs == "?" and opts[cmd]["--json"].const == "-", cmd


def test_fusion_takes_tracker_flags():
    from skyfuse.services.cli.cmd_fusion import tracker_config

    args = build_parser("fusion").parse_args(["fusion", "--tracker", "its", "--depth", "2"])
    cfg = tracker_config(args)
    assert (cfg.tracker, cfg.depth) == ("its", 2)


def test_replay_honours_a_stop_while_waiting_for_a_subscriber(simulated_recording):
    """The wait for a subscriber ends on SIGINT/SIGTERM like every other wait."""
    from skyfuse.services.cli.cmd_replay import _wait_subscriber

    stop = threading.Event()
    threading.Timer(0.2, stop.set).start()
    with open_session(peer()) as s:
        assert _wait_subscriber(s, keys.radar_plots("R1"), 30.0, stop) is False


def test_a_repeated_list_flag_adds_to_the_list_instead_of_replacing_it():
    """``--param radars=3 --param traffic=steady`` used to keep only the last flag (the
    soak benchmark's 'steady' traffic was silently dropped); both spellings now agree."""
    parser = build_parser()
    base = ["simulate", "--scenario", "regional"]
    once = parser.parse_args([*base, "--param", "radars=3,traffic=steady"])
    twice = parser.parse_args([*base, "--param", "radars=3", "--param", "traffic=steady"])
    assert once.param == twice.param == ["radars=3", "traffic=steady"]
    track = parser.parse_args(["eval", "thesis-mtt-5", "--trackers", "its", "--trackers", "lmits"])
    assert track.trackers == ["its", "lmits"]
    assert not hasattr(parser.parse_args(base), "param")  # not given: the model's default
