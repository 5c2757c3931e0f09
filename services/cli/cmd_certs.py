"""``skyfuse certs --out DIR --sensors R1,R2 [--fusion main] [--recorders recorder]
[--clients viewer]``: create the material of a secure local deployment — a test CA, one
certificate and key per process (mutual TLS), the router's access-control policy
``acl.json5`` and one ``{name}.toml`` ``[transport]`` table per process — see
``services.runtime.security`` and docs/deployment.md.

If ``DIR/ca.pem`` exists its CA is reused (new certificates for the listed processes,
a new ``acl.json5`` for exactly the listed processes); existing certificates of the
same names are replaced. Then, e.g.::

    skyfuse router --config DIR/router.toml
    skyfuse fusion --config DIR/fusion-main.toml
    skyfuse sensor --radar R1 --config DIR/sensor-R1.toml
    skyfuse tracks --mode client --connect tls/127.0.0.1:7447 \\
        --tls-root-ca DIR/ca.pem --tls-cert DIR/client-viewer.pem --tls-key DIR/client-viewer.key
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from pydantic import BaseModel, Field, field_validator
from skyfuse.services.runtime.config import add_model_arguments, build_config
from skyfuse.services.runtime.lifecycle import EXIT_OK
from skyfuse.services.runtime.transport import check_endpoint

log = logging.getLogger("skyfuse.certs")


class CertsConfig(BaseModel):
    out: Path = Field(description="Directory for the CA, certificates, acl.json5 and TOMLs")
    sensors: list[str] = Field(default_factory=list, description="Radar ids of the sensors")
    fusion: list[str] = Field(default_factory=lambda: ["main"], description="Fusion ids")
    recorders: list[str] = Field(
        default_factory=lambda: ["recorder"], description="Recorder service names (--name)"
    )
    clients: list[str] = Field(
        default_factory=lambda: ["viewer"], description="Names of track-feed clients"
    )
    hosts: list[str] = Field(
        default_factory=lambda: ["localhost", "127.0.0.1"],
        description="Host names / IP addresses the certificates are valid for (add the "
        "router's, e.g. zenohd)",
    )
    router: str = Field(
        "tls/127.0.0.1:7447", description="The router's endpoint, written into the TOMLs"
    )
    days: int = Field(365, ge=1, le=3650, description="Validity of the certificates, days")

    @field_validator("router")
    @classmethod
    def _router(cls, v: str) -> str:
        return check_endpoint(v)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "certs",
        help="create a test CA, certificates and the access policy of a secure deployment",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_model_arguments(p, CertsConfig)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from skyfuse.services.runtime.security import principals, write_deployment

    cfg = build_config(CertsConfig, args)
    people = principals(cfg.sensors, cfg.fusion, cfg.recorders, cfg.clients)
    reuse = cfg.out if (cfg.out / "ca.pem").is_file() else None
    files = write_deployment(cfg.out, people, cfg.hosts, cfg.router, cfg.days, ca_of=reuse)
    log.info(
        "%s CA in %s; %d files: certificates for %s; acl.json5",
        "reused the" if reuse else "created a",
        cfg.out,
        len(files),
        ", ".join(p.cn for p in people),
    )
    print("\n".join(str(f) for f in files))
    return EXIT_OK
