"""Are two versions of skyfuse tracking the same? Published tracks of a list of
configurations, dumped canonically and compared message by message.

**Run** (with the Python of the skyfuse to test; nothing of skyfuse is imported here, the
command ``python -m skyfuse.services.cli`` of that interpreter does the work)::

    /work/wt-ref/.venv/bin/python benchmarks/track_equivalence.py --out /tmp/eq-ref
    .venv/bin/python benchmarks/track_equivalence.py --out /tmp/eq-new
    python benchmarks/track_equivalence.py --compare /tmp/eq-ref /tmp/eq-new

``--quick`` runs a subset (about 1-2 min on an idle machine), ``--only TEXT`` the
configurations whose name contains TEXT (repeatable), ``--list`` prints the names,
``--jobs N`` runs N configurations at once, ``--track-args "ARGS"`` adds ARGS to every
``skyfuse track`` command (e.g. ``--no-identity``). The simulated inputs are written once into
``--inputs`` (default ``<out>/../track-equivalence-inputs``) and reused by every run, so
that both versions track the same plots even if their simulators differed (the compare
step checks the inputs' SHA-256).

Every configuration is ``skyfuse track INPUT --tracker K --motion M --publish P`` over
one input: the regional scenario (``skyfuse simulate --scenario regional``, 600 s,
seed 3; 120 s in ``--quick``) for every tracker kind and motion model, the thesis
scenarios ``thesis-mtt-5`` and ``thesis-stt`` for a few seeds, and the Barcelona CAT048
recording of ``/work/shared/data`` when it is there. Its dump ``NAME.json.gz`` holds
every message of the output MCAP in file order (topic and JSON body: TrackBatch,
TrackEvent, …), the command, the input's SHA-256 and the run's summary (without its
wall time).

**Compare** prints one line per configuration: ``identical`` (every message equal, float
for float), ``within tolerance`` (same messages, ids, statuses, events; numbers differ by
at most ``--tol`` relative: a vector or matrix relative to its largest entry, a scalar
to itself, or ``--atol`` absolute) with the largest relative difference of the track
states and covariances and of any number, or ``DIFFERENT`` with the first message that
differs beyond the tolerance (its index, topic, time and the path of the field).
``--ignore-identity`` compares the kinematics alone: the tracks' identity fields (every
``Track`` field but the kinematic ones, :data:`KINEMATIC`) and the identity events
(:data:`IDENTITY_EVENTS`) are left out of both sides first, so a version that attributes
identity to the tracks is compared with one that does not. Exit
status 0 when every configuration is identical or within tolerance, 1 otherwise. A run
that fails is dumped too (exit status and last error line): two versions that fail the
same way on a configuration are reported as an ``identical failure``.
"""

from __future__ import annotations

import argparse
import gzip
import hashlib
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from mcap.reader import make_reader

DATA = Path("/work/shared/data")
BCN = DATA / "bcn_20230502_0800_0815_cat048.ast"
BCN_SITES = """[[radar]]
sac = 20
sic = 129
lat = 41.300702
lon = 2.102058
alt = 27.26
"""
KINEMATIC = frozenset(("track_id", "time", "status", "existence", "state", "covariance",
                       "lat", "lon", "alt", "vel_east", "vel_north", "vel_up", "speed",
                       "heading", "radars", "updates"))  # fmt: skip
"""The fields of a ``Track`` that are not identity (what ``--ignore-identity`` keeps)."""
IDENTITY_EVENTS = frozenset(("identity_changed", "identity_conflict", "emergency", "spi"))
"""The event kinds ``--ignore-identity`` leaves out."""
KINDS = ("gnn", "ipda", "its", "lmipda", "lmits", "jipda", "jits")
OWN_DENSITY = ("ipf", "lmipf")
MOTIONS = ("cv", "imm-cv-ct", "imm-cv-singer")


@dataclass(frozen=True)
class Input:
    """A recording to track: simulated (scenario, seed, duration) or a file."""

    name: str
    scenario: str | None = None
    seed: int = 1
    duration: float | None = None
    path: Path | None = None
    sites: str | None = None  # TOML text of the sites of an ASTERIX file


@dataclass(frozen=True)
class Config:
    name: str
    input: Input
    tracker: str
    motion: str | None
    publish: str = "confirmed"
    extra: tuple[str, ...] = field(default_factory=tuple)

    def args(self) -> list[str]:
        out = ["--tracker", self.tracker, "--publish", self.publish]
        if self.motion is not None:
            out += ["--motion", self.motion]
        return out + list(self.extra)


def _cfg(inp: Input, kind: str, motion: str | None, publish="confirmed", *extra) -> Config:
    label = kind if motion is None else f"{kind}-{motion}"
    suffix = "" if publish == "confirmed" else f"-{publish}"
    return Config(f"{inp.name}-{label}{suffix}", inp, kind, motion, publish, tuple(extra))


def configurations(quick: bool) -> list[Config]:
    """The list run by default (or ``--quick``)."""
    if quick:
        reg = Input("regional120-s3", "regional", 3, 120.0)
        mtt = Input("mtt5-s1", "thesis-mtt-5", 1)
        stt = Input("stt-s1", "thesis-stt", 1)
        return [
            _cfg(reg, "lmits", "imm-cv-ct", "all"),
            _cfg(reg, "ipda", "cv"),
            _cfg(reg, "jits", "imm-cv-singer"),
            _cfg(reg, "gnn", "imm-cv-ct"),
            _cfg(reg, "its", "imm-cv-singer"),
            _cfg(reg, "lmipda", "cv"),
            _cfg(reg, "jipda", "imm-cv-ct"),
            _cfg(reg, "ipf", None, "confirmed", "--particles", "300"),
            _cfg(reg, "lmipf", None, "confirmed", "--particles", "300"),
            _cfg(mtt, "lmits", "cv", "all"),
            _cfg(mtt, "jits", "imm-cv-ct", "all"),
            _cfg(mtt, "lmipf", None, "all", "--particles", "300"),
            _cfg(stt, "ipda", "cv", "all"),
        ] + (
            [_cfg(Input("bcn", path=BCN, sites=BCN_SITES), "lmits", "imm-cv-ct")]
            if BCN.exists()
            else []
        )
    reg = Input("regional-s3", "regional", 3, 600.0)
    out = [_cfg(reg, k, m) for k in KINDS for m in MOTIONS]
    out += [_cfg(reg, k, None) for k in OWN_DENSITY]
    out.append(_cfg(reg, "lmits", "imm-cv-ct", "all"))
    for seed in (1, 2, 3):
        mtt = Input(f"mtt5-s{seed}", "thesis-mtt-5", seed)
        stt = Input(f"stt-s{seed}", "thesis-stt", seed)
        pairs = (("its", "cv"), ("lmits", "cv"), ("jits", "cv"), ("ipda", "imm-cv-ct"))
        out += [_cfg(mtt, k, m, "all") for k, m in pairs]
        out += [_cfg(mtt, "lmipf", None, "all")]
        out += [_cfg(stt, k, m, "all") for k, m in
                (("ipda", "cv"), ("its", "cv"), ("lmits", "imm-cv-singer"))]  # fmt: skip
        out += [_cfg(stt, "ipf", None, "all")]
    if BCN.exists():
        bcn = Input("bcn", path=BCN, sites=BCN_SITES)
        out += [_cfg(bcn, "lmits", "imm-cv-ct"), _cfg(bcn, "lmits", "imm-cv-ct", "all"),
                _cfg(bcn, "ipda", "cv"), _cfg(bcn, "jits", "imm-cv-singer"),
                _cfg(bcn, "lmipf", None)]  # fmt: skip
    return out


def _cli(python: str) -> list[str]:
    return [python, "-m", "skyfuse.services.cli"]


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def prepare(inp: Input, inputs: Path, python: str) -> tuple[Path, list[str]]:
    """The input file (simulated once into ``inputs``) and the extra arguments it needs."""
    inputs.mkdir(parents=True, exist_ok=True)
    if inp.path is not None:
        extra = []
        if inp.sites is not None:
            sites = inputs / f"{inp.name}.sites.toml"
            if not sites.exists():
                sites.write_text(inp.sites)
            extra = ["--sites", str(sites)]
        return inp.path, extra
    path = inputs / f"{inp.name}.mcap"
    if not path.exists():
        tmp = path.with_suffix(".tmp.mcap")
        cmd = [*_cli(python), "simulate", "--scenario", inp.scenario, "--seed", str(inp.seed),
               "--out", str(tmp), "--no-progress"]  # fmt: skip
        if inp.duration is not None:
            cmd += ["--duration", str(inp.duration)]
        subprocess.run(cmd, check=True, capture_output=True)
        os.replace(tmp, path)
    return path, []


def read_messages(path: Path) -> tuple[list[str], list[list]]:
    """(topics, [[topic index, JSON body], …]) of an MCAP file in file order."""
    topics: list[str] = []
    index: dict[str, int] = {}
    out = []
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            t = index.setdefault(channel.topic, len(topics))
            if t == len(topics):
                topics.append(channel.topic)
            out.append([t, json.loads(message.data)])
    return topics, out


def run_one(cfg: Config, out_dir: Path, python: str, prepared, track_args=()) -> str:
    path, extra = prepared
    extra = [*extra, *track_args]
    with tempfile.TemporaryDirectory() as tmp:
        mcap = Path(tmp) / "tracks.mcap"
        cmd = [*_cli(python), "track", str(path), "--out", str(mcap), "--no-progress",
               *extra, *cfg.args()]  # fmt: skip
        t0 = time.monotonic()
        r = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.monotonic() - t0
        dump = {
            "name": cfg.name,
            "command": " ".join(["skyfuse track", Path(path).name, *extra[:1], *cfg.args()]),
            "input": {"name": cfg.input.name, "sha256": _sha256(Path(path))},
            "python": python,
        }
        if r.returncode != 0:  # kept: two versions failing the same way are equal
            (out_dir / f"{cfg.name}.err").write_text(r.stderr + r.stdout)
            lines = r.stderr.strip().splitlines() or [""]
            errors = [ln for ln in lines if re.match(r"[\w.]*(Error|Exception)\b", ln)]
            last = (errors or lines)[-1]  # the exception's line, not its detail
            dump["failed"] = {"exit": r.returncode, "error": last}
            with gzip.open(out_dir / f"{cfg.name}.json.gz", "wt") as f:
                json.dump(dump, f)
            return f"{cfg.name}: FAILED (exit {r.returncode}: {last[:80]}; see {cfg.name}.err)"
        topics, messages = read_messages(mcap)
    dump.update(summary=_summary(r.stdout), topics=topics, messages=messages)
    with gzip.open(out_dir / f"{cfg.name}.json.gz", "wt") as f:
        json.dump(dump, f, separators=(",", ":"))
    return f"{cfg.name}: {len(messages)} messages ({wall:.1f} s)"


def _summary(stdout: str) -> dict | None:
    """The JSON summary ``skyfuse track`` prints, without its wall time."""
    for line in reversed(stdout.strip().splitlines()):
        try:
            d = json.loads(line)
        except ValueError:
            continue
        if isinstance(d, dict):
            d.pop("wall_s", None)
            return d
    return None


def run(a) -> int:
    cfgs = [c for c in configurations(a.quick) if not a.only or any(s in c.name for s in a.only)]
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    inputs = Path(a.inputs) if a.inputs else out.parent / "track-equivalence-inputs"
    prepared = {}
    for c in cfgs:  # simulate each input once, before the parallel runs
        if c.input not in prepared:
            prepared[c.input] = prepare(c.input, inputs, a.python)
    t0 = time.monotonic()
    failed = 0
    with ThreadPoolExecutor(max_workers=a.jobs) as pool:
        targs = (a.track_args or "").split()
        jobs = [pool.submit(run_one, c, out, a.python, prepared[c.input], targs) for c in cfgs]
        for j in jobs:
            line = j.result()
            failed += "FAILED" in line
            print(line, flush=True)
    print(f"{len(cfgs)} configurations in {time.monotonic() - t0:.0f} s into {out}")
    return 1 if failed else 0


# ---------------------------------------------------------------------------- compare
@dataclass
class Diff:
    """The comparison of two message bodies: the largest relative difference of any
    number and of the track states / covariances, and the first difference beyond the
    tolerance (path, a, b) or a structural one."""

    tol: float
    atol: float
    max_rel: float = 0.0
    max_rel_path: str = ""
    max_state: float = 0.0
    first: tuple | None = None

    def number(self, path: str, a, b) -> None:
        rel = _rel(a, b)
        self._note(path, rel, abs(a - b) if _finite(a, b) else math.inf)

    def block(self, path: str, a: list, b: list) -> None:
        fa, fb = _flat(a), _flat(b)
        scale = max(max(map(abs, fa), default=0.0), max(map(abs, fb), default=0.0))
        worst, worst_abs = 0.0, 0.0
        for x, y in zip(fa, fb):
            if x == y or (x != x and y != y):
                continue
            d = abs(x - y)
            worst_abs = max(worst_abs, d)
            worst = max(worst, d / scale if scale > 0 and math.isfinite(d) else math.inf)
        if path.rsplit("/", 1)[-1] in ("state", "covariance"):
            self.max_state = max(self.max_state, worst)
        self._note(path, worst, worst_abs)

    def _note(self, path: str, rel: float, absolute: float) -> None:
        if rel > self.max_rel:
            self.max_rel, self.max_rel_path = rel, path
        if rel > self.tol and absolute > self.atol and self.first is None:
            self.first = (path, rel)

    def structure(self, path: str, a, b) -> None:
        if self.first is None:
            self.first = (path, f"{_short(a)} != {_short(b)}")


def _finite(a, b) -> bool:
    return math.isfinite(a) and math.isfinite(b)


def _rel(a, b) -> float:
    if a == b or (a != a and b != b):
        return 0.0
    if not _finite(a, b):
        return math.inf
    return abs(a - b) / max(abs(a), abs(b))


def _flat(v) -> list[float]:
    if isinstance(v, list):
        return [x for item in v for x in _flat(item)]
    return [float(v)]


def _numeric_block(v) -> bool:
    """A non-empty list of numbers, or of such lists (a vector or a matrix)."""
    if not isinstance(v, list) or not v:
        return False
    return all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v) or all(
        _numeric_block(x) for x in v
    )


def _shape(v):
    return [len(v), *_shape(v[0])] if isinstance(v, list) and v else []


def _short(v) -> str:
    s = json.dumps(v)
    return s if len(s) <= 80 else s[:77] + "..."


def compare_values(a, b, path: str, diff: Diff) -> None:
    """Walk two JSON values in parallel, noting numbers' differences in ``diff``."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            diff.structure(path, sorted(a), sorted(b))
            return
        for k in a:
            compare_values(a[k], b[k], f"{path}/{k}", diff)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            diff.structure(path + " (length)", len(a), len(b))
        elif _numeric_block(a) and _numeric_block(b) and _shape(a) == _shape(b):
            diff.block(path, a, b)
        else:
            for i, (x, y) in enumerate(zip(a, b)):
                compare_values(x, y, f"{path}/{i}", diff)
    elif _is_number(a) and _is_number(b):
        if isinstance(a, int) and isinstance(b, int):
            if a != b:
                diff.structure(path, a, b)
        else:
            diff.number(path, float(a), float(b))
    elif a != b or type(a) is not type(b):
        diff.structure(path, a, b)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _load(path: Path) -> dict:
    with gzip.open(path, "rt") as f:
        return json.load(f)


def without_identity(dump: dict) -> dict:
    """``dump`` with the tracks' identity fields and the identity events left out."""
    if "messages" not in dump:
        return dump
    out = []
    for topic, body in dump["messages"]:
        if not isinstance(body, dict):
            out.append([topic, body])
        elif body.get("kind") in IDENTITY_EVENTS:
            continue
        elif "tracks" in body:
            tracks = [{k: v for k, v in t.items() if k in KINEMATIC} for t in body["tracks"]]
            out.append([topic, {**body, "tracks": tracks}])
        else:
            out.append([topic, body])
    return {**dump, "messages": out}


def compare_dumps(da: dict, db: dict, tol: float, atol: float) -> str:
    """One line: identical / within tolerance / DIFFERENT (see the module docstring)."""
    if da["input"]["sha256"] != db["input"]["sha256"]:
        return "DIFFERENT inputs (SHA-256 differs): not comparable"
    fa, fb = da.get("failed"), db.get("failed")
    if fa is not None or fb is not None:
        if fa == fb:
            return f"identical failure (both exit {fa['exit']}: {fa['error'][:90]})"
        return f"DIFFERENT: failed {fa} vs {fb}"
    ma, mb = da["messages"], db["messages"]
    ta, tb = da["topics"], db["topics"]
    if ma == mb and ta == tb:
        return f"identical ({len(ma)} messages)"
    diff = Diff(tol, atol)
    for i, (x, y) in enumerate(zip(ma, mb)):
        if ta[x[0]] != tb[y[0]]:
            diff.structure("topic", ta[x[0]], tb[y[0]])
        else:
            compare_values(x[1], y[1], "", diff)
        if diff.first is not None:
            body = x[1] if isinstance(x[1], dict) else {}
            where = f"message {i} ({ta[x[0]].rsplit('/', 1)[-1]}, time {body.get('time')})"
            return f"DIFFERENT: first at {where} {diff.first[0]}: {diff.first[1]}"
    if len(ma) != len(mb):
        n = min(len(ma), len(mb))
        return f"DIFFERENT: {len(ma)} vs {len(mb)} messages (equal over the first {n})"
    return (
        f"within tolerance ({len(ma)} messages): max relative difference of states and "
        f"covariances {diff.max_state:.2e}, of any number {diff.max_rel:.2e} ({diff.max_rel_path})"
    )


def compare(a, b, tol: float, atol: float, ignore_identity: bool = False) -> int:
    """Compare the dumps of two run directories; one line per configuration."""
    da, db = Path(a), Path(b)
    names = sorted({p.name[:-8] for d in (da, db) for p in d.glob("*.json.gz")})
    bad = 0
    width = max(map(len, names), default=0)
    for name in names:
        pa, pb = da / f"{name}.json.gz", db / f"{name}.json.gz"
        if not pa.exists() or not pb.exists():
            line = f"missing in {'A' if not pa.exists() else 'B'}"
        else:
            x, y = _load(pa), _load(pb)
            if ignore_identity:
                x, y = without_identity(x), without_identity(y)
            line = compare_dumps(x, y, tol, atol)
            if x.get("summary") != y.get("summary") and line.startswith(("identical", "within")):
                line += "; the run summaries differ"
        bad += not line.startswith(("identical", "within"))
        print(f"{name:<{width}}  {line}", flush=True)
    print(f"{len(names)} configurations, {bad} not equal")
    return 1 if bad or not names else 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", help="directory of the dumps of this run")
    p.add_argument("--inputs", help="directory of the simulated inputs (shared by runs)")
    p.add_argument("--quick", action="store_true", help="the quick subset (~1-2 min)")
    p.add_argument("--only", action="append", help="configurations whose name contains this")
    p.add_argument("--list", action="store_true", help="print the configuration names")
    p.add_argument("--jobs", type=int, default=1, help="configurations run at once")
    p.add_argument("--python", default=sys.executable, help="the Python of the skyfuse to run")
    p.add_argument("--compare", nargs=2, metavar=("A", "B"), help="compare two run directories")
    p.add_argument("--tol", type=float, default=1e-9, help="relative tolerance (default 1e-9)")
    p.add_argument("--atol", type=float, default=1e-12, help="absolute tolerance of numbers")
    p.add_argument("--track-args", help="arguments added to every skyfuse track command")
    p.add_argument(
        "--ignore-identity",
        action="store_true",
        help="compare without the tracks' identity fields and identity events",
    )
    a = p.parse_args(argv)
    if a.compare:
        return compare(*a.compare, a.tol, a.atol, a.ignore_identity)
    if a.list:
        for c in configurations(a.quick):
            print(c.name, " ".join(c.args()))
        return 0
    if not a.out:
        p.error("--out DIR is required to run (or --compare A B, --list)")
    return run(a)


if __name__ == "__main__":
    sys.exit(main())
