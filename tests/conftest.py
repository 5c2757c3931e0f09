"""Fixtures shared by the whole test tree (helpers and paths: ``service_support.py``).

* ``simulated_recording(*args)`` — an MCAP recording made by ``skyfuse simulate *args``
  once per test session (cached by its arguments), for tests that only read it.
* ``shared_data`` — the public data directory (``service_support.SHARED_DATA``); the test
  is skipped when it is absent.
* ``independent_decoder`` — ``service_support.independent_asterix_decode`` once its
  virtualenv is made (first use in a session, cached across sessions); the test is
  skipped, with the reason, when asterix-decoder cannot be built here.
* every test gets its own ``XDG_STATE_HOME`` (a temporary directory, inherited by the
  processes it starts): a ``skyfuse fusion`` of one test never resumes the saved state
  of another (``services.fusion.state_store``) nor writes into the user's home.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from service_support import (
    SHARED_DATA,
    IndependentDecoderUnavailable,
    independent_asterix_decode,
    independent_decoder_python,
)


@pytest.fixture(scope="session")
def simulated_recording(tmp_path_factory):
    made: dict[tuple[str, ...], Path] = {}

    def make(*args: str) -> Path:
        if args not in made:
            from skyfuse.services.cli.main import main

            path = tmp_path_factory.mktemp("sim") / "recording.mcap"
            assert main(["simulate", *args, "--out", str(path), "--no-progress"]) == 0
            made[args] = path
        return made[args]

    return make


@pytest.fixture
def shared_data() -> Path:
    if not SHARED_DATA.is_dir():
        pytest.skip(f"{SHARED_DATA} is absent")
    return SHARED_DATA


@pytest.fixture(scope="session")
def independent_decoder():
    try:
        independent_decoder_python()
    except IndependentDecoderUnavailable as e:
        pytest.skip(f"the independent ASTERIX decoder (asterix-decoder) is unavailable: {e}")
    return independent_asterix_decode


@pytest.fixture(autouse=True)
def _private_state_home(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path_factory.mktemp("state")))
