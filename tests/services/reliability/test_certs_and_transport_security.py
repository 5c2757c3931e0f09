"""``skyfuse certs`` output checked with an independent X.509 parser and by Zenoh itself,
and the transport's TLS settings: all-or-nothing, files must exist, the flags reach the
Zenoh configuration, and a listener beyond loopback without TLS is warned about."""

from __future__ import annotations

import json
import logging
import subprocess
import sys
import tomllib

import pytest
import zenoh
from cryptography import x509
from cryptography.hazmat.primitives.asymmetric.padding import PKCS1v15
from cryptography.x509.oid import NameOID
from skyfuse.services.runtime.config import ConfigError
from skyfuse.services.runtime.transport import TransportConfig, warn_exposed, zenoh_config


def certs_cli(out, *args):
    cmd = [sys.executable, "-m", "skyfuse.services.cli", "certs", "--out", str(out)]
    return subprocess.run([*cmd, *args], capture_output=True, timeout=120)


def cn_of(path) -> str:
    cert = x509.load_pem_x509_certificate(path.read_bytes())
    return cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value


def test_certs_command_writes_a_consistent_deployment(tmp_path):
    out = tmp_path / "d"
    r = certs_cli(out, "--sensors", "R1,R2", "--clients", "viewer", "--hosts", "zenohd,127.0.0.1")
    assert r.returncode == 0, r.stderr.decode()
    ca = x509.load_pem_x509_certificate((out / "ca.pem").read_bytes())
    names = ["router", "fusion-main", "sensor-R1", "sensor-R2", "recorder", "client-viewer"]
    for name in names:
        cert = x509.load_pem_x509_certificate((out / f"{name}.pem").read_bytes())
        assert cn_of(out / f"{name}.pem") == name
        assert cert.issuer == ca.subject
        ca.public_key().verify(  # signed by the CA (raises otherwise)
            cert.signature, cert.tbs_certificate_bytes, PKCS1v15(), cert.signature_hash_algorithm
        )
        san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
        assert "zenohd" in san.get_values_for_type(x509.DNSName)
        assert (out / f"{name}.key").stat().st_mode & 0o077 == 0  # private key: owner only
        tcfg = TransportConfig(**tomllib.loads((out / f"{name}.toml").read_text())["transport"])
        conf = zenoh_config(tcfg)  # the TOML is a valid transport config for Zenoh
        tls = json.loads(conf.get_json("transport/link/tls"))
        assert tls["enable_mtls"] and tls["connect_certificate"].endswith(f"{name}.pem")
    acl = json.loads((out / "acl.json5").read_text())
    assert acl["default_permission"] == "deny"
    assert {s["id"] for s in acl["subjects"]} == set(names) - {"router"}
    conf = zenoh.Config()
    conf.insert_json5("access_control", (out / "acl.json5").read_text())  # Zenoh accepts it
    # a second run reuses the CA: certificates of both runs verify against one ca.pem
    before = (out / "ca.pem").read_bytes()
    assert certs_cli(out, "--sensors", "R1,R2,R3").returncode == 0
    assert (out / "ca.pem").read_bytes() == before and cn_of(out / "sensor-R3.pem") == "sensor-R3"


def test_tls_settings_go_together_and_must_exist(tmp_path):
    f = tmp_path / "x.pem"
    f.write_text("x")
    with pytest.raises(ValueError, match="go together"):
        TransportConfig(tls_root_ca=f)
    with pytest.raises(ValueError, match="is not a file"):
        TransportConfig(tls_root_ca=f, tls_cert=f, tls_key=tmp_path / "missing.key")
    cfg = TransportConfig(tls_root_ca=f, tls_cert=f, tls_key=f)
    conf = zenoh_config(cfg)  # no --listen: loopback, over TLS
    assert json.loads(conf.get_json("listen/endpoints")) == ["tls/127.0.0.1:0"]
    bad = tmp_path / "acl.json5"
    bad.write_text("{ enabled: true, rules: 7 }")
    with pytest.raises(ConfigError, match="acl"):
        zenoh_config(TransportConfig(acl=bad))


def test_listening_beyond_loopback_without_tls_is_warned(caplog):
    with caplog.at_level(logging.WARNING, logger="skyfuse.services.runtime.transport"):
        eps = ["tcp/127.0.0.1:7447", "tcp/0.0.0.0:7448", "tls/0.0.0.0:7449", "tcp/[::]:7450"]
        assert warn_exposed(eps, tls=False) == ["tcp/0.0.0.0:7448", "tcp/[::]:7450"]
        # with TLS configured, a plain TCP listener even on loopback bypasses it
        assert warn_exposed(["tcp/127.0.0.1:7447", "tls/0.0.0.0:7449"], tls=True) == [
            "tcp/127.0.0.1:7447"
        ]
    assert sum("without TLS" in r.getMessage() for r in caplog.records) == 3
