"""``skyfuse schemas --out DIR``: write the JSON Schema of every wire message."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from pydantic import BaseModel, Field
from skyfuse import schemas
from skyfuse.services.runtime.config import add_model_arguments, build_config


class SchemasConfig(BaseModel):
    out: Path = Field(Path("schemas-json"), description="Directory to write *.schema.json into")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("schemas", help="write the JSON Schemas of the wire messages")
    add_model_arguments(p, SchemasConfig)
    p.set_defaults(func=run)


def write_schemas(out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for model in sorted({m for m in schemas.MODELS.values()}, key=lambda m: m.__name__):
        path = out / f"{model.__name__}.schema.json"
        path.write_text(json.dumps(model.model_json_schema(), indent=2) + "\n")
        written.append(path)
    keys = {
        "prefix": schemas.keys.PREFIX,
        "keys": {
            "radar site": "skyfuse/@v1/radar/{id}/site",
            "radar plots": "skyfuse/@v1/radar/{id}/plots",
            "radar liveliness": "skyfuse/@v1/radar/{id}/alive",
            "fusion tracks": "skyfuse/@v1/fusion/{id}/tracks",
            "fusion events": "skyfuse/@v1/fusion/{id}/events",
            "fusion status": "skyfuse/@v1/fusion/{id}/status",
            "fusion snapshot (queryable)": "skyfuse/@v1/fusion/{id}/snapshot",
            "simulation truth": schemas.keys.SIM_TRUTH,
        },
    }
    path = out / "keys.json"
    path.write_text(json.dumps(keys, indent=2) + "\n")
    written.append(path)
    return written


def run(args: argparse.Namespace) -> int:
    cfg = build_config(SchemasConfig, args)
    for path in write_schemas(cfg.out):
        print(path)
    return 0
