"""A state format that cannot execute code when it is read (issue 14 §3–4).

The fusion service's snapshot (its tracker, feed, frame, sites and watermarks) is one
bytes blob, the same in the state directory and on the network (the standby's
``fusion/{id}/state`` key): a NumPy ``.npz`` archive (uncompressed zip) whose member
``manifest`` is a JSON document (UTF-8, as a ``uint8`` array) and whose members
``a0``, ``a1``, … are the numeric arrays it refers to. Reading it runs
``numpy.load(..., allow_pickle=False)`` and ``json.loads`` only, then rebuilds **only**
the types of an explicit allow-list:

* JSON scalars (``null``, booleans, integers, floats with ``NaN``/``Infinity``,
  strings); ``list``, ``tuple``, ``set``, ``frozenset``, ``deque`` (with ``maxlen``),
  ``dict`` and ``collections.Counter`` (any encodable keys);
* NumPy arrays and scalars of boolean, integer, unsigned, float or complex dtype (the
  manifest states dtype and shape; a member that differs is refused);
* the enums and pydantic models of :data:`ENUMS` / :data:`MODELS` (rebuilt by
  ``Enum(value)`` / ``model_validate``: validated);
* the classes of :data:`CLASSES`, rebuilt as ``object.__new__(cls)`` with their
  attributes set one by one (no ``__init__``, ``__setstate__`` or ``__reduce__`` runs);
  the classes of :data:`BUILT` by calling them with their saved constructor arguments
  (objects holding pyproj transformers);
* the functions of :data:`FUNCTIONS` (by name) and NumPy random generators (bit
  generator name and state).

Objects met twice are written once and referenced (``ref``), as pickle does: objects
shared between the tracker and the feed stay shared. Anything else — a pickle, an
unknown type, a member with another dtype or shape, a reference out of range, nesting
deeper than :data:`MAX_DEPTH`, a compressed member (zip bomb), more than ``max_bytes`` —
is a :class:`StateRejected` with a reason from :data:`REASONS`, never another exception.
Saving a type outside the allow-list raises :class:`StateUnsupported` (a new tracker
part must be added to the list; ``tests/services/reliability`` round-trips every
tracker kind).
"""

from __future__ import annotations

import importlib
import io
import json
import zipfile
from collections import Counter, deque
from types import FunctionType

import numpy as np

FORMAT = 2
"""Version of the snapshot layout (1 was the pickle of earlier versions)."""
MAX_DEPTH = 64
"""Deepest nesting accepted in a manifest (the tracker's state is about 10 deep)."""
REASONS = (
    "too large",
    "not a state archive",
    "compressed member",
    "malformed manifest",
    "format version",
    "unknown type",
    "bad array",
    "bad value",
    "too deep",
    "other fusion id",
    "malformed header",
    "too old",
)
"""Every reason a blob is refused for (bounded vocabulary, counted by the callers)."""

_F, _T = "skyfuse.fusion.", "skyfuse.fusion.tracker."
CLASSES = frozenset(
    {
        _T + "tracker.Tracker",
        _T + "tracker.TrackerOutput",
        _T + "tracker.OutputPrediction",
        _T + "tracker.TrackEventRecord",
        _T + "measurements.MeasurementBatch",
        _T + "measurements.SectorCoverage",
        _T + "initiation.PlotBuffer",
        _T + "oosm_pass.OutOfSequence",
        _T + "oosm.LastStep",
        _T + "reidentification.TerminatedTracks",
        _T + "existence.ExistenceChain",
        _T + "components.Mixture",
        _T + "component_slots.ComponentSlots",
        _T + "density.gaussian_mixture.GaussianMixtureDensity",
        _T + "density.imm_mixture.IMMMixtureDensity",
        _T + "density.imm_mixture.IMMComponents",
        _T + "density.imm_mixture.ModeTransition",
        _T + "density.imm_mixture.ReachGate",
        _F + "particles.density.ParticleDensity",
        _F + "models.cv.ConstantVelocity",
        _F + "models.coordinated_turn.CoordinatedTurn",
        _F + "models.singer.Singer",
        _F + "frames.system_frame.SystemFrame",
        _F + "registration.bias_filter.BiasFilter",
        _F + "registration.common_target.PairBuffer",
        _F + "registration.common_target.PlotColumns",
        _F + "registration.estimator.RegistrationEstimator",
        "skyfuse.services.fusion.feed.TrackTable",
        "skyfuse.services.fusion.registration_link.RegistrationLink",
        "skyfuse.services.runtime.seen_batches.SeenBatches",
    }
)
"""Classes rebuilt attribute by attribute."""
BUILT = {_F + "frames.stereographic.Stereographic": ("lat0", "lon0")}
"""Classes rebuilt by calling them with these attributes (they hold pyproj objects)."""
MODELS = frozenset(
    {
        _T + "config.TrackerConfig",
        _F + "registration.config.RegistrationConfig",
        "skyfuse.schemas.site.RadarSite",
        "skyfuse.schemas.tracks.FrameSpec",
    }
)
ENUMS = frozenset(
    {
        "skyfuse.schemas.tracks.FrameKind",
        "skyfuse.schemas.site.RadarKind",
        _F + "registration.config.RegistrationMode",
    }
)
FUNCTIONS = frozenset(
    _T + f"associators.associate_{n}" for n in ("single", "lm", "joint", "gnn")
)  # fmt: skip
BIT_GENERATORS = frozenset({"PCG64", "PCG64DXSM", "Philox", "SFC64", "MT19937"})
_DTYPE_KINDS = "biufc"
_SCALARS = (type(None), bool, int, float, str)
_SEQUENCES = {list: "list", tuple: "tuple", set: "set", frozenset: "frozenset"}


class StateRejected(ValueError):
    """A blob that is not a valid snapshot: ``reason`` (one of :data:`REASONS`) and a
    short ``detail``."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason, self.detail = reason, detail[:200]


class StateUnsupported(TypeError):
    """Saving an object whose type is not in the allow-list."""


def qualname(t: type) -> str:
    return f"{t.__module__}.{t.__qualname__}"


def _resolve(name: str):
    module, _, attr = name.rpartition(".")
    obj = importlib.import_module(module)
    return getattr(obj, attr)


def _attributes(obj) -> dict:
    out = dict(vars(obj)) if hasattr(obj, "__dict__") else {}
    for cls in type(obj).__mro__:
        for slot in getattr(cls, "__slots__", ()):
            if hasattr(obj, slot) and slot != "__dict__":
                out[slot] = getattr(obj, slot)
    return out


class _Encoder:
    """Object graph → JSON-able manifest + list of arrays."""

    def __init__(self) -> None:
        self.arrays: list[np.ndarray] = []
        self.memo: dict[int, int] = {}
        self.keep: list = []  # holds encoded objects so that their id()s stay unique

    def encode(self, o):
        if type(o) in _SCALARS:
            return o
        ref = self.memo.get(id(o))
        if ref is not None:
            return {"$": "ref", "id": ref}
        self.memo[id(o)] = n = len(self.memo)
        self.keep.append(o)
        node = self._node(o)
        node["id"] = n
        return node

    def _array(self, a: np.ndarray) -> dict:
        if a.dtype.kind not in _DTYPE_KINDS or a.dtype.fields is not None:
            raise StateUnsupported(f"array of dtype {a.dtype}")
        self.arrays.append(a if a.flags.c_contiguous else a.copy(order="C"))
        return {"i": len(self.arrays) - 1, "dtype": a.dtype.str, "shape": list(a.shape)}

    def _node(self, o) -> dict:
        t = type(o)
        if t in _SEQUENCES:
            return {"$": _SEQUENCES[t], "v": [self.encode(v) for v in o]}
        if t is deque:
            return {"$": "deque", "v": [self.encode(v) for v in o], "maxlen": o.maxlen}
        if t is dict or t is Counter:
            kind = "dict" if t is dict else "counter"
            return {"$": kind, "v": [[self.encode(k), self.encode(v)] for k, v in o.items()]}
        if t is np.ndarray:
            return {"$": "array", **self._array(o)}
        if isinstance(o, np.generic):
            return {"$": "scalar", **self._array(np.asarray(o))}
        if isinstance(o, np.random.Generator):
            bits = o.bit_generator
            return {"$": "rng", "t": type(bits).__name__, "v": self.encode(bits.state)}
        return self._named(o, qualname(t))

    def _named(self, o, name: str) -> dict:
        if name in ENUMS:
            return {"$": "enum", "t": name, "v": o.value}
        if name in MODELS:
            return {"$": "model", "t": name, "v": o.model_dump(mode="json")}
        if name in BUILT:
            return {"$": "build", "t": name, "v": [self.encode(getattr(o, a)) for a in BUILT[name]]}
        if name in CLASSES:
            attrs = _attributes(o)
            return {"$": "obj", "t": name, "v": {k: self.encode(v) for k, v in attrs.items()}}
        if isinstance(o, FunctionType) and f"{o.__module__}.{o.__qualname__}" in FUNCTIONS:
            return {"$": "fn", "t": f"{o.__module__}.{o.__qualname__}"}
        raise StateUnsupported(f"type {name} is not in the state allow-list")


def dumps(state) -> bytes:
    """``state`` (an object graph of allow-listed types) as one blob."""
    enc = _Encoder()
    manifest = {"format": FORMAT, "root": enc.encode(state)}
    text = json.dumps(manifest, separators=(",", ":")).encode()
    members = {"manifest": np.frombuffer(text, np.uint8)}
    members.update({f"a{i}": a for i, a in enumerate(enc.arrays)})
    buf = io.BytesIO()
    np.savez(buf, **members)
    return buf.getvalue()


class _Decoder:
    """Manifest + arrays → object graph, allow-listed types only."""

    def __init__(self, arrays) -> None:
        self.arrays = arrays
        self.memo: dict[int, object] = {}

    def decode(self, node, depth: int = 0):
        if depth > MAX_DEPTH:
            raise StateRejected("too deep", f"nesting beyond {MAX_DEPTH}")
        if node is None or type(node) in (bool, int, float, str):
            return node
        if type(node) is not dict or not isinstance(node.get("$"), str):
            raise StateRejected("malformed manifest", f"node of type {type(node).__name__}")
        kind = node["$"]
        if kind == "ref":
            if node.get("id") not in self.memo:
                raise StateRejected("malformed manifest", "reference to no object")
            return self.memo[node["id"]]
        handler = _HANDLERS.get(kind)
        if handler is None:
            raise StateRejected("unknown type", f"node kind {kind[:40]!r}")
        return handler(self, node, depth + 1)

    def keep(self, node, obj):
        ident = node.get("id")
        if type(ident) is not int or ident in self.memo:
            raise StateRejected("malformed manifest", "object id missing or repeated")
        self.memo[ident] = obj
        return obj

    def items(self, node, depth: int) -> list:
        v = node.get("v")
        if type(v) is not list:
            raise StateRejected("malformed manifest", f"{node['$']} without a list")
        return [self.decode(x, depth) for x in v]

    def array(self, node) -> np.ndarray:
        i, dtype, shape = node.get("i"), node.get("dtype"), node.get("shape")
        if type(i) is not int or not 0 <= i < len(self.arrays):
            raise StateRejected("bad array", f"array index {i!r}")
        a = self.arrays[i]
        if a.dtype.kind not in _DTYPE_KINDS or a.dtype.fields is not None:
            raise StateRejected("bad array", f"dtype {a.dtype}")
        if a.dtype.str != dtype or list(a.shape) != shape:
            raise StateRejected(
                "bad array", f"a{i}: {a.dtype.str} {list(a.shape)} ≠ manifest {dtype} {shape}"
            )
        return a


def _sequence(kind):
    make = {"list": list, "tuple": tuple, "set": set, "frozenset": frozenset}[kind]

    def handle(dec: _Decoder, node, depth):
        if make is list:  # mutable: registered first, may be referenced from inside
            out = dec.keep(node, [])
            out.extend(dec.items(node, depth))
            return out
        try:
            return dec.keep(node, make(dec.items(node, depth)))
        except TypeError as e:  # unhashable member of a set
            raise StateRejected("bad value", f"{kind}: {e}") from None

    return handle


def _deque(dec: _Decoder, node, depth):
    maxlen = node.get("maxlen")
    if maxlen is not None and (type(maxlen) is not int or maxlen < 0):
        raise StateRejected("bad value", f"deque maxlen {maxlen!r}")
    out = dec.keep(node, deque(maxlen=maxlen))
    out.extend(dec.items(node, depth))
    return out


def _dict(dec: _Decoder, node, depth):
    pairs = node.get("v")
    if type(pairs) is not list:
        raise StateRejected("malformed manifest", "dict without a list")
    out = dec.keep(node, Counter() if node["$"] == "counter" else {})
    for pair in pairs:
        if type(pair) is not list or len(pair) != 2:
            raise StateRejected("malformed manifest", "dict entry is not a pair")
        key = dec.decode(pair[0], depth)
        try:
            out[key] = dec.decode(pair[1], depth)
        except TypeError as e:
            raise StateRejected("bad value", f"dict key: {e}") from None
    return out


def _array(dec: _Decoder, node, depth):
    return dec.keep(node, dec.array(node).copy())


def _scalar(dec: _Decoder, node, depth):
    a = dec.array(node)
    if a.ndim != 0:
        raise StateRejected("bad array", "scalar with a shape")
    return dec.keep(node, a[()])


def _named_type(node, allowed) -> type:
    name = node.get("t")
    if not isinstance(name, str) or name not in allowed:
        raise StateRejected("unknown type", str(name)[:80])
    return _resolve(name)


def _enum(dec: _Decoder, node, depth):
    cls = _named_type(node, ENUMS)
    try:
        return dec.keep(node, cls(node.get("v")))
    except (ValueError, TypeError) as e:
        raise StateRejected("bad value", f"{cls.__name__}: {e}") from None


def _model(dec: _Decoder, node, depth):
    cls = _named_type(node, MODELS)
    try:
        return dec.keep(node, cls.model_validate(node.get("v")))
    except ValueError as e:  # pydantic.ValidationError is a ValueError
        raise StateRejected("bad value", f"{cls.__name__}: {str(e)[:120]}") from None


def _build(dec: _Decoder, node, depth):
    cls = _named_type(node, BUILT)
    args = dec.items(node, depth)
    if len(args) != len(BUILT[node["t"]]) or not all(type(a) is float for a in args):
        raise StateRejected("bad value", f"{cls.__name__} arguments")
    try:
        return dec.keep(node, cls(*args))
    except ValueError as e:
        raise StateRejected("bad value", f"{cls.__name__}: {e}") from None


def _object(dec: _Decoder, node, depth):
    cls = _named_type(node, CLASSES)
    attrs = node.get("v")
    if type(attrs) is not dict or not all(k.isidentifier() and k[:2] != "__" for k in attrs):
        raise StateRejected("malformed manifest", f"{cls.__name__} attributes")
    obj = dec.keep(node, object.__new__(cls))
    for k, v in attrs.items():
        value = dec.decode(v, depth)
        try:
            object.__setattr__(obj, k, value)
        except (AttributeError, TypeError) as e:  # e.g. a slot the class does not have
            raise StateRejected("bad value", f"{cls.__name__}.{k}: {e}") from None
    return obj


def _function(dec: _Decoder, node, depth):
    return _named_type(node, FUNCTIONS)


def _rng(dec: _Decoder, node, depth):
    name = node.get("t")
    if name not in BIT_GENERATORS:
        raise StateRejected("unknown type", f"bit generator {str(name)[:40]}")
    bits = getattr(np.random, name)()
    try:
        bits.state = dec.decode(node.get("v"), depth)
    except (ValueError, TypeError, KeyError) as e:
        raise StateRejected("bad value", f"{name} state: {e}") from None
    return dec.keep(node, np.random.Generator(bits))


_HANDLERS = {
    **{k: _sequence(k) for k in ("list", "tuple", "set", "frozenset")},
    "deque": _deque,
    "dict": _dict,
    "counter": _dict,
    "array": _array,
    "scalar": _scalar,
    "enum": _enum,
    "model": _model,
    "build": _build,
    "obj": _object,
    "fn": _function,
    "rng": _rng,
}


def _open(blob: bytes, max_bytes: int) -> dict[str, np.ndarray]:
    """The archive's members (checked: a zip of uncompressed ``.npy`` members only)."""
    if len(blob) > max_bytes:
        raise StateRejected("too large", f"{len(blob)} bytes > {max_bytes}")
    try:
        with zipfile.ZipFile(io.BytesIO(blob)) as z:
            infos = z.infolist()
        if any(i.compress_type != zipfile.ZIP_STORED for i in infos):
            raise StateRejected("compressed member")
        if sum(i.file_size for i in infos) > len(blob):
            raise StateRejected("not a state archive", "member sizes beyond the blob")
        with np.load(io.BytesIO(blob), allow_pickle=False) as z:
            return {name: z[name] for name in z.files}
    except StateRejected:
        raise
    except Exception as e:  # zipfile/numpy: any malformed archive or object array
        raise StateRejected("not a state archive", f"{type(e).__name__}: {e}") from None


def loads(blob: bytes, *, max_bytes: int = 256_000_000):
    """The object graph of a blob made by :func:`dumps`; :class:`StateRejected` if it is
    not one (see the module docstring). Never executes code from the blob."""
    members = _open(blob, max_bytes)
    raw = members.pop("manifest", None)
    if raw is None or raw.dtype != np.uint8 or raw.ndim != 1:
        raise StateRejected("not a state archive", "no manifest")
    try:
        manifest = json.loads(raw.tobytes())
    except (ValueError, RecursionError) as e:
        raise StateRejected("malformed manifest", f"{type(e).__name__}") from None
    if type(manifest) is not dict or manifest.get("format") != FORMAT:
        fmt = manifest.get("format") if type(manifest) is dict else None
        raise StateRejected("format version", f"{fmt!r} (expected {FORMAT})")
    arrays = []
    for i in range(len(members)):
        if f"a{i}" not in members:
            raise StateRejected("not a state archive", f"member a{i} missing")
        arrays.append(members[f"a{i}"])
    try:
        return _Decoder(arrays).decode(manifest.get("root"))
    except StateRejected:
        raise
    except RecursionError:
        raise StateRejected("too deep", "recursion") from None
    except Exception as e:  # anything else the rebuilding met: still a rejection
        raise StateRejected("bad value", f"{type(e).__name__}: {e}") from None
