"""docker-compose.secure.yml cannot run here (no Docker engine): check what it references.
The ``certs`` service's command is run for real (into a temporary directory standing for
the ``/certs`` volume); every other service's command parses with the real CLI, its
transport is a TLS client of the router with the certificate of its own identity, the
router's listen port is the published one, and the router's policy lists every identity."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.x509.oid import NameOID
from skyfuse.services.cli.main import build_parser
from skyfuse.services.runtime.config import build_config
from skyfuse.services.runtime.transport import endpoint_port, transport_config

yaml = pytest.importorskip("yaml")
ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def compose() -> dict:
    return yaml.safe_load((ROOT / "docker-compose.secure.yml").read_text())


@pytest.fixture(scope="module")
def certs(compose, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("certs")
    text = compose["services"]["certs"]["command"][0]
    m = re.search(r"skyfuse (certs .*?) &&", text)
    argv = [out.as_posix() if a == "/certs" else a for a in shlex.split(m.group(1))]
    args = build_parser().parse_args(argv)
    assert args.func(args) == 0
    return out


def local(value: str, certs: Path) -> str:
    if value.startswith("/certs/"):
        return str(certs / value[len("/certs/") :])
    if value.startswith("/etc/skyfuse/"):
        return str(ROOT / "deploy" / Path(value).name)
    return value


def identity(args) -> str:
    module = args.func.__module__
    if module.endswith("cmd_sensor"):
        return f"sensor-{args.radar}"
    if module.endswith("cmd_fusion"):
        from skyfuse.services.fusion.service import FusionConfig

        cfg = build_config(FusionConfig, args, toml_path=args.config, section="fusion")
        return f"fusion-{cfg.fusion_id}"
    if module.endswith("cmd_record"):
        from skyfuse.services.recording.recorder import RecorderConfig

        return build_config(RecorderConfig, args, toml_path=args.config, section="record").name
    raise AssertionError(module)


def test_every_service_is_a_tls_client_with_its_own_identity(compose, certs, monkeypatch):
    acl = json.loads((certs / "acl.json5").read_text())
    listed = {cn for s in acl["subjects"] for cn in s["cert_common_names"]}
    seen = set()
    for name, svc in compose["services"].items():
        if name in ("certs", "router"):
            continue
        with monkeypatch.context() as m:
            for k, v in svc["environment"].items():
                m.setenv(k, local(str(v), certs))
            args = build_parser().parse_args([local(a, certs) for a in svc["command"]])
            tcfg = transport_config(args, toml_path=getattr(args, "config", None))
        assert tcfg.mode == "client" and tcfg.connect == ["tls/zenohd:7447"], name
        assert tcfg.tls and tcfg.acl is None
        cert = x509.load_pem_x509_certificate(tcfg.tls_cert.read_bytes())
        cn = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value
        assert cn == identity(args) and cn in listed, (name, cn)
        assert "skyfuse-certs:/certs:ro" in svc["volumes"]
        seen.add(cn)
    assert seen == listed - {"client-viewer"}  # the viewer is the host's client


def test_router_listens_on_tls_only_with_the_policy(compose, certs):
    svc = compose["services"]["router"]
    args = build_parser().parse_args([local(a, certs) for a in svc["command"]])
    tcfg = transport_config(args, toml_path=args.config)
    assert all(ep.startswith("tls/") for ep in tcfg.listen)
    assert tcfg.acl == certs / "acl.json5" and tcfg.tls
    published = {int(p.split(":")[0]) for p in svc["ports"]}
    assert {endpoint_port(ep) for ep in tcfg.listen} == published
    assert "zenohd" in svc["networks"]["default"]["aliases"]
    san = x509.load_pem_x509_certificate(tcfg.tls_cert.read_bytes()).extensions
    names = san.get_extension_for_class(x509.SubjectAlternativeName).value
    assert "zenohd" in names.get_values_for_type(x509.DNSName)


@pytest.mark.parametrize("name", ["docker-compose.yml", "docker-compose.secure.yml"])
def test_fusion_state_is_on_a_named_volume(name, monkeypatch):
    """The fusion service's state dir (from its environment and TOML, as the CLI builds
    it) lies on a named volume of the compose file, whose mount point the image creates
    owned by the service user (Dockerfile), so a recreated container resumes."""
    from skyfuse.services.fusion.service import FusionConfig

    doc = yaml.safe_load((ROOT / name).read_text())
    svc = doc["services"]["fusion"]
    for k, v in svc["environment"].items():
        monkeypatch.setenv(k, str(v))
    args = build_parser().parse_args(svc["command"])
    args.config = str(ROOT / "deploy" / Path(args.config).name)
    cfg = build_config(
        FusionConfig, args, toml_path=args.config, section="fusion", env_prefix="SKYFUSE_FUSION_"
    )
    mounts = dict(v.rsplit(":", 1)[0].split(":") if v.count(":") == 2 else v.split(":")
                  for v in svc["volumes"])  # fmt: skip
    volume = next(vol for vol, target in mounts.items() if cfg.state_dir.is_relative_to(target))
    assert volume in doc["volumes"]  # a named volume, not the container's own layer
    assert cfg.snapshot_interval is not None  # snapshots on
    target = Path(mounts[volume])
    dockerfile = (ROOT / "Dockerfile").read_text()
    assert (
        f"mkdir -p /data {target}" in dockerfile and f"chown skyfuse /data {target}" in dockerfile
    )
