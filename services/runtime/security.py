"""Secure deployment material: a test certificate authority, one certificate per process
(mutual TLS), the Zenoh access-control policy (ACL) of the router, and one ``[transport]``
TOML per process.

Identities are certificate *common names*: ``router``, ``fusion-{id}``,
``sensor-{radar id}``, the recorder's service name (``skyfuse record --name``, default
``recorder``), ``client-{name}``. The router (``skyfuse
router`` or ``zenohd``) listens on TLS only, requires a client certificate signed by the
CA (``enable_mtls``) and enforces the ACL; every other process is a Zenoh *client* of it,
so all traffic passes through the one place that checks it. The policy
(:func:`acl_policy`), default **deny**:

* ``sensor-R`` may publish (put, liveliness, the site queryable) only under
  ``radar/R/**``, plus its own ``service/sensor-R/**`` status and token, and the keys of
  its plots' advanced publisher, ``radar/R/plots/@adv/**`` (the cache queryable that
  answers receivers that missed batches, the heartbeat; ``**`` never matches the verbatim
  chunk ``@adv``, so they need rules of their own);
* ``fusion-F`` may publish only under ``fusion/F/**`` (tracks, events, status, snapshot
  queryable, the ``state`` snapshots for its standby, the election tokens, a standby's
  own Status) and its service keys, and may read every radar (its plots' heartbeats and
  caches ``radar/*/plots/@adv/**`` included) and ``fusion/F/**`` (so its instances —
  same identity, other hosts — follow each other);
* the recorder ``N`` may read everything but the fusion ``state`` snapshots (and the
  plots' heartbeats and caches) and publish only its own service keys;
* ``client-C`` may read the fusion feeds (tracks, events, status, snapshot query,
  registration, standby Status) and nothing else — not the ``state`` snapshots;
* everyone may look up service liveliness under ``service/**`` (``--wait-for``).

Zenoh filters *ingress* (what a peer sends to the router) and *egress* (what the router
delivers to it): a publication reaches a subscriber only if the publisher may put
(ingress) and the subscriber may receive (egress) on that key.

The certificates are for test and local deployments (RSA 2048 / SHA-256, 1 year); in
production use the organisation's PKI with the same common names.
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import json
from dataclasses import dataclass
from pathlib import Path

from skyfuse.schemas import keys

P = keys.PREFIX
_PUBLISH = ["put", "delete", "declare_queryable", "reply", "liveliness_token"]
"""What a writer sends (ingress at the router)."""
_READ_IN = ["declare_subscriber", "query", "declare_liveliness_subscriber", "liveliness_query"]
"""What a reader sends (ingress); the same messages reach a writer (egress) to tell it
that someone listens (Zenoh publishers send only to matching subscribers)."""
_READ_OUT = ["put", "delete", "reply", "declare_queryable", "liveliness_token"]
"""What a reader receives (egress)."""


@dataclass(frozen=True)
class Principal:
    """One identity: its certificate common name and its role."""

    role: str  # router, fusion, sensor, recorder, client
    name: str  # radar id, fusion id, recorder or client name ("" for the router)

    @property
    def cn(self) -> str:
        if self.role == "router":
            return "router"
        if self.role == "recorder":  # its service name (``skyfuse record --name``)
            return self.name
        return f"{self.role}-{self.name}"


def principals(
    sensors: list[str], fusion: list[str], recorders: list[str], clients: list[str]
) -> list[Principal]:
    """The router and every listed process (ids checked as key chunks)."""
    out = [Principal("router", "")]
    for role, names in (
        ("fusion", fusion),
        ("sensor", sensors),
        ("recorder", recorders),
        ("client", clients),
    ):
        out += [Principal(role, keys.check_id(n, f"{role} name")) for n in names]
    return out


def _rule(rid: str, messages: list[str], flows: list[str], key_exprs: list[str]) -> dict:
    return {
        "id": rid,
        "messages": messages,
        "flows": flows,
        "permission": "allow",
        "key_exprs": key_exprs,
    }


def _rules_for(p: Principal) -> list[dict]:
    """The allow rules of one principal (see the module docstring)."""
    own_service = f"{P}/service/{p.cn}/**"
    rules = _reader(f"{p.cn}-services", [f"{P}/service/*/alive"])
    if p.role == "sensor":
        mine = [f"{P}/radar/{p.name}/**", f"{P}/radar/{p.name}/plots/@adv/**"]
        # told of the recovery queries and heartbeat subscribers of every reader
        interest = [f"{P}/**", f"{P}/**/@adv/**"]
        rules += _writer(p.cn, [*mine, own_service, f"{P}/sim/**"], interest)
    elif p.role == "fusion":
        own = [f"{P}/fusion/{p.name}/**", own_service, f"{P}/service/fusion/**"]
        # its own fusion/F/** too: the election tokens of its instances (fusion.standby)
        read = [f"{P}/radar/**", PLOTS_ADV, f"{P}/fusion/{p.name}/**"]
        rules += _writer(p.cn, own) + _reader(p.cn, read)
    elif p.role == "recorder":
        everything = [f"{P}/radar/**", PLOTS_ADV, *FEED_KEYS, f"{P}/sim/**", f"{P}/service/**"]
        read = [f"{P}/**", f"{P}/**/@adv/**"]  # it subscribes (and recovers) skyfuse/@v1/**
        rules += _writer(p.cn, [own_service]) + _reader(p.cn, read, receive=everything)
    elif p.role == "client":
        rules += _reader(p.cn, [f"{P}/fusion/**"], receive=FEED_KEYS)
    return rules


PLOTS_ADV = f"{P}/radar/*/plots/@adv/**"
"""The keys of the plots' advanced publishers (``services.runtime.transport``): their
heartbeats and the cache queryables that answer receivers that missed batches."""
FEED_KEYS = [
    *(f"{P}/fusion/*/{k}" for k in ("tracks", "events", "status", "snapshot", "registration")),
    f"{P}/fusion/*/standby/*/status",
]
"""What a client (and the recorder) may receive of the fusion keys: not ``state``, not
the election tokens."""


def _writer(cn: str, key_exprs: list[str], interest: list[str] | None = None) -> list[dict]:
    """May publish on ``key_exprs`` and be told of their readers. Zenoh checks a
    declaration's key expression for *inclusion* in a rule's: a reader declares wildcards
    (``radar/*/plots``), which only the whole key space includes; so every writer learns
    which key expressions are subscribed or queried (``interest``, default the whole key
    space; not what is published on them) — without it a publisher stops sending after
    its first sample."""
    return [
        _rule(f"{cn}-write", _PUBLISH, ["ingress"], key_exprs),
        _rule(f"{cn}-write-interest", _READ_IN, ["egress"], interest or [f"{P}/**"]),
    ]


def _reader(cn: str, key_exprs: list[str], receive: list[str] | None = None) -> list[dict]:
    """May subscribe to and query ``key_exprs`` and receive what is published there (only
    on ``receive`` if given: the router checks each delivered sample's concrete key, so
    a subscriber of ``**`` receives nothing else)."""
    return [
        _rule(f"{cn}-read", _READ_IN, ["ingress"], key_exprs),
        _rule(f"{cn}-read-data", _READ_OUT, ["egress"], receive or key_exprs),
    ]


def acl_policy(people: list[Principal]) -> dict:
    """The router's ``access_control`` configuration (Zenoh ≥ 1.0 format)."""
    rules, subjects, policies = [], [], []
    for p in people:
        if p.role == "router":
            continue
        mine = _rules_for(p)
        rules += mine
        subjects.append({"id": p.cn, "cert_common_names": [p.cn]})
        policies.append({"id": p.cn, "rules": [r["id"] for r in mine], "subjects": [p.cn]})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


# --- certificates -------------------------------------------------------------------
def _name(cn: str):
    from cryptography import x509
    from cryptography.x509.oid import NameOID

    return x509.Name(
        [
            x509.NameAttribute(NameOID.ORGANIZATION_NAME, "skyfuse test deployment"),
            x509.NameAttribute(NameOID.COMMON_NAME, cn),
        ]
    )


def _key():
    from cryptography.hazmat.primitives.asymmetric import rsa

    return rsa.generate_private_key(public_exponent=65537, key_size=2048)


def _write(path: Path, data: bytes, private: bool = False) -> None:
    path.write_bytes(data)
    if private:
        path.chmod(0o600)


def _pem_key(key) -> bytes:
    from cryptography.hazmat.primitives import serialization

    return key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )


def _pem_cert(cert) -> bytes:
    from cryptography.hazmat.primitives import serialization

    return cert.public_bytes(serialization.Encoding.PEM)


def _ca_usage():
    from cryptography import x509

    flags = dict.fromkeys(
        ("content_commitment", "key_encipherment", "data_encipherment", "key_agreement"),
        False,
    )
    return x509.KeyUsage(
        digital_signature=True,
        key_cert_sign=True,
        crl_sign=True,
        encipher_only=False,
        decipher_only=False,
        **flags,
    )


def make_ca(out: Path, days: int = 365):
    """Create ``ca.pem`` and ``ca.key`` (a self-signed CA) in ``out``; ``(cert, key)``."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes

    key = _key()
    now = dt.datetime.now(dt.UTC)
    cert = (
        x509.CertificateBuilder()
        .subject_name(_name("skyfuse test CA"))
        .issuer_name(_name("skyfuse test CA"))
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=days))
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(_ca_usage(), critical=True)
        .sign(key, hashes.SHA256())
    )
    _write(out / "ca.pem", _pem_cert(cert))
    _write(out / "ca.key", _pem_key(key), private=True)
    return cert, key


def issue(out: Path, ca, cn: str, hosts: list[str], days: int = 365) -> tuple[Path, Path]:
    """Create ``{cn}.pem`` / ``{cn}.key`` signed by ``ca = (cert, key)``, valid as a TLS
    server for ``hosts`` (DNS names or IP addresses) and as a TLS client."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes
    from cryptography.x509.oid import ExtendedKeyUsageOID

    ca_cert, ca_key = ca
    key = _key()
    alt = []
    for h in hosts:
        try:
            alt.append(x509.IPAddress(ipaddress.ip_address(h)))
        except ValueError:
            alt.append(x509.DNSName(h))
    now = dt.datetime.now(dt.UTC)
    cert = (
        x509.CertificateBuilder()
        .subject_name(_name(cn))
        .issuer_name(ca_cert.subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=days))
        .add_extension(x509.SubjectAlternativeName(alt), critical=False)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.ExtendedKeyUsage(
                [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]
            ),
            critical=False,
        )
        .sign(ca_key, hashes.SHA256())
    )
    cert_path, key_path = out / f"{cn}.pem", out / f"{cn}.key"
    _write(cert_path, _pem_cert(cert))
    _write(key_path, _pem_key(key), private=True)
    return cert_path, key_path


def transport_toml(p: Principal, directory: Path, router: str, listen: str | None = None) -> str:
    """The ``[transport]`` table of ``p``: client of ``router`` (the router itself
    listens on ``listen`` and enforces ``acl.json5``), certificates in ``directory``."""
    d = directory.resolve()
    lines = ["[transport]"]
    if p.role == "router":
        lines += ['mode = "router"', f"listen = [{json.dumps(listen or router)}]"]
        lines.append(f"acl = {json.dumps(str(d / 'acl.json5'))}")
    else:
        lines += ['mode = "client"', f"connect = [{json.dumps(router)}]"]
    lines += [
        f"tls_root_ca = {json.dumps(str(d / 'ca.pem'))}",
        f"tls_cert = {json.dumps(str(d / (p.cn + '.pem')))}",
        f"tls_key = {json.dumps(str(d / (p.cn + '.key')))}",
    ]
    return "\n".join(lines) + "\n"


def write_deployment(
    out: Path,
    people: list[Principal],
    hosts: list[str],
    router: str = "tls/127.0.0.1:7447",
    days: int = 365,
    *,
    ca_of: Path | None = None,
) -> list[Path]:
    """Write the CA (or reuse ``ca_of``'s ``ca.pem``/``ca.key``), one certificate, key and
    ``{cn}.toml`` per principal, and ``acl.json5``; return the files written."""
    from cryptography import x509
    from cryptography.hazmat.primitives import serialization

    out.mkdir(parents=True, exist_ok=True)
    if ca_of is None:
        ca = make_ca(out, days)
        written = [out / "ca.pem", out / "ca.key"]
    else:
        ca = (
            x509.load_pem_x509_certificate((ca_of / "ca.pem").read_bytes()),
            serialization.load_pem_private_key((ca_of / "ca.key").read_bytes(), None),
        )
        written = []
    for p in people:
        written += issue(out, ca, p.cn, hosts, days)
        toml = out / f"{p.cn}.toml"
        toml.write_text(transport_toml(p, out, router))
        written.append(toml)
    acl = out / "acl.json5"
    acl.write_text(json.dumps(acl_policy(people), indent=2) + "\n")
    written.append(acl)
    return written
