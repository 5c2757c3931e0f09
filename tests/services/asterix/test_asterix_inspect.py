"""``skyfuse inspect`` on ASTERIX files: categories, sensors, record counts, rejections."""

from __future__ import annotations

import json
import subprocess
import sys
from collections import Counter

import pytest
from service_support import ROOT, SHARED_DATA
from skyfuse.services.asterix.pcap import iter_file_datagrams, split_datablocks
from skyfuse.services.cli.cmd_inspect import inspect_asterix

LEBL = {
    "lebl_20160510_2200_2215_mlat.ast": ("CAT010 0/107", 10),
    "lebl_20160510_2200_2215_smr.ast": ("CAT010 0/7", 10),
    "lebl_20160510_2200_2215_adsb.ast": ("CAT021 0/107", 21),
    "lebl_20201002_0800_0815_mlat.ast": ("CAT010 0/107", 10),
    "lebl_20201002_0800_0815_smr.ast": ("CAT010 0/7", 10),
}


@pytest.mark.parametrize("name", sorted(LEBL))
def test_inspect_describes_the_lebl_files(name):
    path = SHARED_DATA / name
    if not path.exists():
        pytest.skip(f"{path} absent")
    sensor, cat = LEBL[name]
    blocks: Counter = Counter()
    for dgram in iter_file_datagrams(path, Counter()):
        for c, _ in split_datablocks(dgram.payload, Counter(), raw_stream=True):
            blocks[c] += 1
    info = inspect_asterix(path)
    assert info["categories"] == {f"cat{cat:03d}": blocks[cat]}  # one record per block
    (got,) = info["sensors"]
    assert got["sensor"] == sensor and sum(got["records"].values()) == blocks[cat]
    assert 890.0 < got["last_tod_s"] - got["first_tod_s"] < 900.0  # 15 minutes
    if "smr" in name:
        assert got["addresses"] == 0 and got["track_numbers"] > 50
        assert got["records"]["type 2"] == got["records"]["type 3"] > 880
    else:
        assert 10 < got["addresses"] < 40
    assert not info["rejected"]


def test_inspect_command_prints_json_and_refuses_other_files(tmp_path):
    path = SHARED_DATA / "lebl_20160510_2200_2215_adsb.ast"
    if not path.exists():
        pytest.skip(f"{path} absent")
    run = [sys.executable, "-m", "skyfuse.services.cli", "inspect"]
    done = subprocess.run([*run, str(path), "--json"], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    info = json.loads(done.stdout)
    assert info["format"] == "asterix" and info["sensors"][0]["addresses"] == 29
    other = tmp_path / "notes.txt"
    other.write_text("not a recording\n")
    done = subprocess.run([*run, str(other)], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 1 and "not an MCAP recording" in done.stderr
    assert "no ASTERIX block of a decoded category" in done.stderr
