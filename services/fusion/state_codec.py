"""A state format that cannot execute code when it is read (docs/reliability.md).

The fusion service's snapshot is one bytes blob, the same in the state directory and on
the network (the standby's ``fusion/{id}/state`` key): a NumPy ``.npz`` archive
(uncompressed zip) whose member ``manifest`` is a JSON document (UTF-8, as a ``uint8``
array) and whose members ``a0``, ``a1``, … are the numeric arrays it refers to.

What it carries is a tree of plain values, the snapshots of the owners of the state
(``to_snapshot()``, :mod:`schemas.snapshot`): ``dict`` with ``str`` keys, ``list``,
``str``, ``int``, ``float`` (with ``NaN``/``Infinity``), ``bool``, ``None`` and NumPy
arrays of boolean, integer, unsigned or float dtype. No type is rebuilt: the owners read
their named values back and check them against their declarations. Reading runs
``numpy.load(..., allow_pickle=False)`` and ``json.loads`` only; the manifest's nodes are
JSON scalars, JSON arrays (lists), ``{"$": "dict", "v": {…}}`` and ``{"$": "array", "i":
member, "dtype": …, "shape": […]}``. Anything else — a pickle, an unknown node kind, a
member with another dtype or shape, nesting deeper than :data:`MAX_DEPTH`, a compressed
member (zip bomb), more than ``max_bytes``, a manifest of another :data:`FORMAT` — is a
:class:`StateRejected` with a reason from :data:`REASONS`, never another exception.
Writing a value outside that vocabulary raises :class:`StateUnsupported`.
"""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np

FORMAT = 3
"""Version of the container (1: the pickle of earlier versions; 2: every object's
attributes with an allow-list of types to rebuild; 3: plain values only)."""
MAX_DEPTH = 64
"""Deepest nesting accepted in a manifest (the service's state is about 8 deep)."""
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
_DTYPE_KINDS = "biuf"
_SCALARS = (type(None), bool, int, float, str)


class StateRejected(ValueError):
    """A blob that is not a valid snapshot: ``reason`` (one of :data:`REASONS`) and a
    short ``detail``."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason, self.detail = reason, detail[:200]


class StateUnsupported(TypeError):
    """Saving a value outside the snapshot vocabulary (module docstring)."""


class _Encoder:
    """A tree of plain values → JSON-able manifest + list of arrays."""

    def __init__(self) -> None:
        self.arrays: list[np.ndarray] = []

    def encode(self, o, depth: int = 0):
        if depth > MAX_DEPTH:
            raise StateUnsupported(f"nesting beyond {MAX_DEPTH}")
        t = type(o)
        if t in _SCALARS:
            return o
        if t is list:
            return [self.encode(v, depth + 1) for v in o]
        if t is dict:
            if not all(type(k) is str for k in o):
                raise StateUnsupported("a dict with keys that are not str")
            return {"$": "dict", "v": {k: self.encode(v, depth + 1) for k, v in o.items()}}
        if t is np.ndarray:
            return self._array(o)
        if isinstance(o, np.bool_ | np.integer | np.floating):
            return o.item()
        raise StateUnsupported(f"type {t.__module__}.{t.__qualname__} in a snapshot")

    def _array(self, a: np.ndarray) -> dict:
        if a.dtype.kind not in _DTYPE_KINDS or a.dtype.fields is not None:
            raise StateUnsupported(f"array of dtype {a.dtype}")
        self.arrays.append(a if a.flags.c_contiguous else a.copy(order="C"))
        return {
            "$": "array",
            "i": len(self.arrays) - 1,
            "dtype": a.dtype.str,
            "shape": list(a.shape),
        }


def dumps(state) -> bytes:
    """``state`` (a tree of plain values, see the module docstring) as one blob."""
    enc = _Encoder()
    manifest = {"format": FORMAT, "root": enc.encode(state)}
    text = json.dumps(manifest, separators=(",", ":")).encode()
    members = {"manifest": np.frombuffer(text, np.uint8)}
    members.update({f"a{i}": a for i, a in enumerate(enc.arrays)})
    buf = io.BytesIO()
    np.savez(buf, **members)
    return buf.getvalue()


class _Decoder:
    """Manifest + arrays → the tree of plain values."""

    def __init__(self, arrays) -> None:
        self.arrays = arrays

    def decode(self, node, depth: int = 0):
        if depth > MAX_DEPTH:
            raise StateRejected("too deep", f"nesting beyond {MAX_DEPTH}")
        if node is None or type(node) in (bool, int, float, str):
            return node
        if type(node) is list:
            return [self.decode(v, depth + 1) for v in node]
        if type(node) is not dict or not isinstance(node.get("$"), str):
            raise StateRejected("malformed manifest", f"node of type {type(node).__name__}")
        kind = node["$"]
        if kind == "dict":
            v = node.get("v")
            if type(v) is not dict:
                raise StateRejected("malformed manifest", "dict without a mapping")
            return {k: self.decode(x, depth + 1) for k, x in v.items()}
        if kind == "array":
            return self.array(node).copy()
        raise StateRejected("unknown type", f"node kind {kind[:40]!r}")

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
    """The tree of plain values of a blob made by :func:`dumps`; :class:`StateRejected`
    if it is not one (see the module docstring). Never executes code from the blob."""
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
        raise StateRejected(
            "format version",
            f"snapshot container format {fmt!r}: this version of skyfuse reads format {FORMAT}",
        )
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
    except Exception as e:  # anything else the decoding met: still a rejection
        raise StateRejected("bad value", f"{type(e).__name__}: {e}") from None
