"""docker-compose.yml cannot run here (no Docker engine): check what it references.

Every skyfuse service's command parses with the real CLI parser and its configuration
(TOML mounted from deploy/, environment) validates; endpoints name the router service on
the port the router listens on and publishes; sensors name radars of the scenario and
wait for services that exist; the fusion frame is the scenario's frame."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest
from skyfuse.services.cli.main import build_parser
from skyfuse.services.runtime.config import build_config
from skyfuse.services.runtime.transport import ENDPOINT_RE, transport_config

yaml = pytest.importorskip("yaml")

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def compose() -> dict:
    return yaml.safe_load((ROOT / "docker-compose.yml").read_text())


def skyfuse_services(compose: dict) -> dict[str, dict]:
    return {
        n: s for n, s in compose["services"].items() if s.get("image", "").startswith("skyfuse")
    }


def host_path(path: str) -> Path:
    """Map a container path of the image to the repository (Dockerfile COPY deploy/*.toml)."""
    assert path.startswith("/etc/skyfuse/"), path
    return ROOT / "deploy" / Path(path).name


def parse(service: dict, monkeypatch):
    for k, v in (service.get("environment") or {}).items():
        monkeypatch.setenv(k, str(v))
    args = build_parser().parse_args(service["command"])
    toml = getattr(args, "config", None)
    if toml is not None:
        args.config = str(host_path(toml))
    return args


def test_every_command_is_a_valid_skyfuse_invocation(compose, monkeypatch):
    svcs = skyfuse_services(compose)
    assert {"fusion", "recorder"} <= set(svcs)
    assert sum(n.startswith("sensor-") for n in svcs) == 3
    for name, svc in svcs.items():
        with monkeypatch.context() as m:
            args = parse(svc, m)
            tcfg = transport_config(args, toml_path=getattr(args, "config", None))
            assert tcfg.mode == "client" and tcfg.connect, name
            module = args.func.__module__
            if module.endswith("cmd_fusion"):
                from skyfuse.services.cli.cmd_fusion import tracker_config
                from skyfuse.services.fusion.service import FusionConfig

                build_config(FusionConfig, args, toml_path=args.config, section="fusion",
                             env_prefix="SKYFUSE_FUSION_")  # fmt: skip
                assert tracker_config(args).tracker == "lmits"
            elif module.endswith("cmd_record"):
                from skyfuse.services.recording.recorder import RecorderConfig

                rc = build_config(RecorderConfig, args, toml_path=args.config, section="record")
                data_volumes = [v.split(":")[1] for v in svc.get("volumes", [])]
                assert any(str(rc.out).startswith(d) for d in data_volumes), rc.out
            elif module.endswith("cmd_sensor"):
                from skyfuse.services.sensors.config import SensorServiceConfig
                from skyfuse.services.sensors.simulated import load_scenario

                sc_cfg = build_config(SensorServiceConfig, args)
                # the radar exists in the scenario (a short one: the ids do not depend on it)
                _, site = load_scenario(sc_cfg.model_copy(update={"duration": 30.0}))
                assert name == f"sensor-{site.radar_id.lower()}"
                others = {
                    f"sensor-{n.split('-', 1)[1].upper()}" for n in svcs if n.startswith("sensor-")
                }
                assert set(sc_cfg.wait_for) == {"fusion", "recorder"} | (
                    others - {f"sensor-{site.radar_id}"}
                )
            else:
                pytest.fail(f"unexpected command {module} in {name}")


def test_endpoints_and_ports_agree(compose, monkeypatch):
    router = compose["services"]["zenohd"]
    conf_mount = next(v for v in router["volumes"] if "zenohd.json5" in v)
    host_file, container_file = conf_mount.split(":")[:2]
    assert container_file in router["command"]
    zconf = json.loads((ROOT / host_file).read_text())
    assert zconf["mode"] == "router"
    assert zconf["scouting"]["multicast"]["enabled"] is False
    listen_ports = {int(ENDPOINT_RE.match(e).group(3)) for e in zconf["listen"]["endpoints"]}
    published = {int(p.split(":")[1]) for p in router["ports"]}
    assert published <= listen_ports
    for name, svc in skyfuse_services(compose).items():
        with monkeypatch.context() as m:
            args = parse(svc, m)
            tcfg = transport_config(args, toml_path=getattr(args, "config", None))
        for ep in tcfg.connect:
            host, port = ENDPOINT_RE.match(ep).group(2, 3)
            assert host == "zenohd" and int(port) in listen_ports, (name, ep)
            assert "zenohd" in svc["depends_on"]


def test_fusion_frame_is_the_scenario_frame(compose):
    import tomllib

    from skyfuse.fusion.sim import build_scenario

    fusion_toml = tomllib.loads((ROOT / "deploy" / "fusion.toml").read_text())["fusion"]
    radars = {n for n in skyfuse_services(compose) if n.startswith("sensor-")}
    sc = build_scenario("regional", seed=1, radars=len(radars))
    assert fusion_toml["frame_kind"] == sc.frame.kind.value
    assert abs(fusion_toml["frame_lat0"] - sc.frame.lat0) < 1e-3
    assert abs(fusion_toml["frame_lon0"] - sc.frame.lon0) < 1e-3


def test_dockerfile_copies_what_exists_and_runs_skyfuse():
    text = (ROOT / "Dockerfile").read_text()
    for src in re.findall(r"^COPY\s+(.+?)\s+\S+$", text, flags=re.M):
        for part in src.split():
            assert list(ROOT.glob(part)), f"Dockerfile copies {part} which does not exist"
    assert 'ENTRYPOINT ["skyfuse"]' in text
    assert os.path.isfile(ROOT / "pyproject.toml")
    # `pip install .` in the image needs every folder the package is built from
    import tomllib

    dirs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    before_install = text[: text.index("RUN pip install .")]
    for folder in dirs.values():
        assert re.search(rf"^COPY {folder} ", before_install, re.M), f"Dockerfile misses {folder}/"


def test_dockerfile_compiles_the_kernels_into_a_cache_the_runtime_user_owns():
    """numba ignores a cache directory it cannot write (it tries a temporary file there):
    the image's site-packages belongs to root, so the kernels are compiled at build time
    into NUMBA_CACHE_DIR, which is then given to the user the services run as."""
    text = (ROOT / "Dockerfile").read_text()
    cache = re.search(r"^ENV NUMBA_CACHE_DIR=(\S+)$", text, flags=re.M)
    assert cache, "the image sets no NUMBA_CACHE_DIR"
    run = text[text.index("RUN pip install .") :]
    run = run[: run.index("\n\n")]
    assert run.index("pip install .") < run.index("skyfuse warmup")
    user = re.search(r"^USER (\S+)$", text, flags=re.M).group(1)
    assert re.search(rf"chown -R {user} .*\"\$NUMBA_CACHE_DIR\"", run), run
    assert text.index("ENV NUMBA_CACHE_DIR") < text.index("RUN pip install .")


def test_the_image_and_the_install_command_run_the_kernel_warmup():
    """The image builds with ``skyfuse warmup`` (a valid invocation of the real parser, run
    by the build's root user, before the cache is handed to the runtime user), and the
    README's install command runs it before the first ``skyfuse demo``, so neither a
    container start nor a user's first run compiles the kernels."""
    text = (ROOT / "Dockerfile").read_text()
    steps = re.findall(r"&& (skyfuse [^\\\n]+?)\s*(?:\\|$)", text, flags=re.M)
    assert steps == ["skyfuse warmup"], steps
    args = build_parser().parse_args(steps[0].split()[1:])
    assert args.func.__module__.endswith("cmd_warmup")
    assert text.index("skyfuse warmup") < text.index("chown -R")
    assert text.index("skyfuse warmup") < text.index("\nUSER ")
    readme = (ROOT / "README.md").read_text()
    first = next(line for line in readme.splitlines() if "pip install -e" in line)
    assert first.startswith("python3 -m pip install -e")
    cmds = [c.strip() for c in first.split("&&")]
    assert cmds[1:] == ["skyfuse warmup", "skyfuse demo"], first
