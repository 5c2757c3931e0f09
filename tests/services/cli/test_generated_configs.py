"""Every network command takes the ``<name>.toml`` that ``skyfuse certs`` writes for it
(the README says so; finding of the live probe: ``skyfuse tracks --config
secure/client-viewer.toml`` exited 2, ``unrecognized arguments``; ``skyfuse replay`` had no
``--config`` either).

``skyfuse certs`` runs as a process; then each command runs in this process with its
generated TOML up to the point where it opens its Zenoh session, which is intercepted:
the transport configuration it was about to use must be the file's (client of the
router, mutual TLS with the identity's certificate; the router: listening with the
access policy). The commands that never open a session (simulate, track, eval, inspect,
schemas, certs) and ``demo`` (which starts its own loopback network) take no transport
TOML."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from skyfuse.services.cli import main as cli_main
from skyfuse.services.cli.main import command_modules
from skyfuse.services.runtime.transport import transport_config

ROUTER = "tls/127.0.0.1:17447"
NETWORK_COMMANDS = {
    # command: (its TOML, the other arguments it needs)
    "router": ("router.toml", []),
    "fusion": ("fusion-main.toml", []),
    "sensor": ("sensor-LYBE.toml", ["--radar", "LYBE"]),
    "record": ("recorder.toml", ["--out", "{tmp}/r.mcap"]),
    "replay": ("sensor-LYBE.toml", ["--sample"]),
    "tracks": ("client-viewer.toml", ["--snapshot"]),
    "cat062": ("client-viewer.toml", ["--udp", "127.0.0.1:9"]),
}
OFFLINE = {"simulate", "track", "eval", "inspect", "schemas", "certs", "demo", "warmup"}


class _Opened(Exception):
    """Raised where the command would open its Zenoh session; carries its transport."""

    def __init__(self, cfg) -> None:
        super().__init__("session")
        self.cfg = cfg


class _Flag:
    grace = 4.5

    def install(self):
        return self

    def is_set(self) -> bool:
        return False


@pytest.fixture(scope="module")
def secure(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("secure")
    r = subprocess.run(
        [sys.executable, "-m", "skyfuse.services.cli", "certs", "--out", str(d), "--sensors",
         "LYBE", "--router", ROUTER],
        capture_output=True, timeout=120,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr.decode()
    return d


def test_every_network_command_is_listed():
    names = {m.rsplit(".cmd_", 1)[1] for m in command_modules()}
    assert names == set(NETWORK_COMMANDS) | OFFLINE


@pytest.mark.parametrize("command", sorted(NETWORK_COMMANDS))
def test_command_runs_with_its_generated_toml(command, secure, tmp_path, monkeypatch):
    toml, extra = NETWORK_COMMANDS[command]
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    module = __import__(f"skyfuse.services.cli.cmd_{command}", fromlist=["run"])

    def opened(cfg, *a, **kw):
        raise _Opened(cfg)

    for name in ("run_service", "open_session"):
        if hasattr(module, name):
            monkeypatch.setattr(module, name, opened)
    if hasattr(module, "StopFlag"):
        monkeypatch.setattr(module, "StopFlag", _Flag)
    argv = [command, "--config", str(secure / toml), *(a.format(tmp=tmp_path) for a in extra)]
    with pytest.raises(_Opened) as got:
        cli_main.main(argv)
    expected = transport_config(toml_path=secure / toml)
    if command == "router":
        expected = expected.model_copy(update={"mode": "router"})
        assert expected.acl is not None and expected.listen == [ROUTER]
    else:
        assert expected.mode == "client" and expected.connect == [ROUTER]
    assert expected.tls
    assert got.value.cfg == expected
