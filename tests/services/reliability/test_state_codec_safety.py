"""The snapshot format (``services.fusion.state_codec``) cannot execute code and refuses
malformed or hostile blobs with a reason; every tracker kind round-trips; a snapshot of
the format before the declared snapshots is refused naming both versions.

References: a pickle payload that would create a file if it were unpickled (the file
must not appear); archives and manifests built here by hand with ``zipfile`` / ``json``
(unknown node kinds, arrays that differ from the manifest, a compressed member, deep
nesting, track-store columns with a wrong number of rows); for the round trip, the feed
of a core that never stopped; and ``data/state_b062918.npz.gz``, the ``state.npz`` a
fusion core of commit b062918 saved (``Persistence.save`` after 10 s of the regional
scenario, seed 5, 2 targets, 3 radars; gzip-compressed here)."""

from __future__ import annotations

import gzip
import io
import json
import pickle
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.fusion.tracker.registry import TRACKERS, own_density_kinds
from skyfuse.services.fusion.pipeline import TrackPipeline
from skyfuse.services.fusion.service import FusionConfig, FusionCore
from skyfuse.services.fusion.state_codec import REASONS, StateRejected, loads
from skyfuse.services.fusion.state_store import StateStore, capture, restore

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def scenario():
    sc = build_scenario("regional", seed=3, duration=30.0, targets=5, radars=3)
    events = list(Simulator(sc, seed=3).run(truth=False))
    batches = sorted((e.message for e in events if e.kind == "plots"), key=lambda b: b.time_end)
    return sc.sites, batches


def _core(sites, tcfg: TrackerConfig) -> FusionCore:
    cfg = FusionConfig(sites=sites, future_tolerance=None, snapshot_interval=None)
    return FusionCore(cfg, lambda frame: TrackPipeline(frame, tcfg, fusion_id="main"))


def _feed(core: FusionCore, batches) -> list[bytes]:
    out = []
    for b in batches:
        core.on_plots(b, 0.0)
        for o in core.poll(flush=True):
            out.append(o.tracks.to_json_bytes())
    return out


def _blob(core: FusionCore, tmp_path) -> bytes:
    store = StateStore(tmp_path / "s", "main", max_age=60, id_horizon=60)
    return store.serialise(capture(core), 1)


def _state_of_a_run(scenario, tmp_path, tcfg=None):
    sites, batches = scenario
    core = _core(sites, tcfg or TrackerConfig())
    _feed(core, batches[:50])
    return core, _blob(core, tmp_path)


def _kinds():
    out = [(k, "cv") for k in TRACKERS]
    return [*out, ("ipda", "imm-cv-ct"), ("jits", "imm-cv-singer")]


@pytest.mark.parametrize("kind, motion", _kinds())
def test_every_tracker_kind_round_trips_to_the_same_feed(kind, motion, scenario, tmp_path):
    sites, batches = scenario
    extra = {"particles": 64} if kind in own_density_kinds() else {}
    tcfg = TrackerConfig(tracker=kind, motion=motion, **extra)
    ref = _core(sites, tcfg)
    _feed(ref, batches[:50])
    store = StateStore(tmp_path / "s", "main", max_age=60, id_horizon=60)
    saved = store.check(store.serialise(capture(ref), 1))
    again = _core(sites, tcfg)
    assert restore(again, saved) is None
    again._next_full = ref._next_full = float("inf")
    a, b = _feed(again, batches[50:80]), _feed(ref, batches[50:80])
    assert len(a) == len(b) > 5 and a == b


def test_a_state_before_the_first_batch_is_a_valid_snapshot(scenario, tmp_path):
    """A standby receives snapshots before the first batch (no frame, no tracker yet):
    they pass the check, and resuming one restores the sites and no tracks."""
    core = _core(scenario[0], TrackerConfig())
    store = StateStore(tmp_path / "s", "main", max_age=60, id_horizon=60)
    saved = store.check(store.serialise(capture(core), 1))
    assert saved["frame"] is None and saved["pipeline"] is None
    fresh = _core([], TrackerConfig())
    assert restore(fresh, saved) == "no tracker state saved yet"
    assert sorted(fresh.radars) == sorted(s.radar_id for s in scenario[0])


class _Exploit:
    """Unpickling this creates a file: the proof that pickle executes code."""

    def __init__(self, path) -> None:
        self.path = str(path)

    def __reduce__(self):
        return (open, (self.path, "w"))


def test_a_pickle_payload_is_refused_without_running_it(tmp_path):
    marker = tmp_path / "pwned"
    payload = pickle.dumps(_Exploit(marker))
    pickle.loads(payload).close()  # the control: unpickled, it runs
    assert marker.exists()
    marker.unlink()
    for blob in (payload, _npz({"manifest": np.array([_Exploit(marker)], dtype=object)})):
        with pytest.raises(StateRejected) as e:
            loads(blob)
        assert e.value.reason == "not a state archive"
    assert not marker.exists()


def _npz(members: dict, compress=False) -> bytes:
    buf = io.BytesIO()
    (np.savez_compressed if compress else np.savez)(buf, **members)
    return buf.getvalue()


def _members(blob: bytes) -> dict:
    with np.load(io.BytesIO(blob), allow_pickle=False) as z:
        return {n: z[n] for n in z.files}


def _with_manifest(blob: bytes, edit) -> bytes:
    m = _members(blob)
    manifest = json.loads(m["manifest"].tobytes())
    edit(manifest, m)
    m["manifest"] = np.frombuffer(json.dumps(manifest).encode(), np.uint8)
    return _npz(m)


def _find(node, pred):
    """The first manifest node (depth first) for which ``pred`` holds."""
    if isinstance(node, dict):
        if pred(node):
            return node
        children = node.values()
    elif isinstance(node, list):
        children = node
    else:
        return None
    for c in children:
        hit = _find(c, pred)
        if hit is not None:
            return hit
    return None


def _set_unknown_type(manifest, _m):
    node = _find(manifest, lambda n: n.get("$") == "dict")
    node.update({"$": "obj", "t": "os._wrap_close"})


def _function_eval(manifest, _m):
    node = _find(manifest, lambda n: n.get("$") == "dict")
    node.clear()
    node.update({"$": "fn", "t": "builtins.eval"})


def _array_shape_lies(manifest, m):
    node = _find(manifest, lambda n: n.get("$") == "array" and len(n["shape"]) == 2)
    m[f"a{node['i']}"] = np.zeros((node["shape"][0] + 1, node["shape"][1]))


def _dict_without_a_mapping(manifest, _m):
    node = _find(manifest, lambda n: n.get("$") == "dict")
    node["v"] = [{"$": "array", "i": 0}]


def _node_without_a_kind(manifest, _m):
    node = _find(manifest, lambda n: n.get("$") == "dict")
    node["v"] = {"x": {"i": 0, "dtype": "<f8", "shape": []}}


@pytest.mark.parametrize(
    "edit, reason",
    [
        (_set_unknown_type, "unknown type"),
        (_function_eval, "unknown type"),
        (_array_shape_lies, "bad array"),
        (_dict_without_a_mapping, "malformed manifest"),
        (_node_without_a_kind, "malformed manifest"),
        (lambda m, _: m.update(format=2), "format version"),
        (lambda m, _: m.update(root={"$": "obj", "t": "builtins.object", "v": {}}), "unknown type"),
        (lambda m, _: m.update(root={"$": "__reduce__", "v": []}), "unknown type"),
    ],
)
def test_tampered_manifests_are_refused_with_a_reason(edit, reason, scenario, tmp_path):
    _, blob = _state_of_a_run(scenario, tmp_path)
    with pytest.raises(StateRejected) as e:
        loads(_with_manifest(blob, edit))
    assert e.value.reason == reason


def test_compressed_deep_and_oversized_blobs_are_refused(scenario, tmp_path):
    _, blob = _state_of_a_run(scenario, tmp_path)
    bomb = _npz(_members(blob), compress=True)
    with pytest.raises(StateRejected, match="compressed member"):
        loads(bomb)
    deep = []
    for _ in range(1, 200):
        deep = [deep]
    m = {"manifest": np.frombuffer(json.dumps({"format": 3, "root": deep}).encode(), np.uint8)}
    with pytest.raises(StateRejected, match="too deep"):
        loads(_npz(m))
    with pytest.raises(StateRejected, match="too large"):
        loads(blob, max_bytes=len(blob) - 1)


def test_per_track_arrays_with_a_wrong_number_of_rows_are_inconsistent(scenario, tmp_path):
    core, blob = _state_of_a_run(scenario, tmp_path)
    n = len(core.pipeline.tracker.ids)
    assert n > 3

    def more_rows(manifest, m):  # a well-formed manifest: the column exist with n + 1 rows
        node = _find(manifest, lambda d: "exist" in d.get("v", {}) and "ids" in d["v"])
        ref = node["v"]["exist"]
        m[f"a{ref['i']}"] = np.zeros((n + 1, 2))
        ref["shape"] = [n + 1, 2]

    store = StateStore(tmp_path / "s", "main", max_age=60, id_horizon=60)
    saved = store.check(_with_manifest(blob, more_rows))  # a well-formed blob ...
    fresh = _core(scenario[0], TrackerConfig())
    why = restore(fresh, saved)  # ... whose state does not fit its declaration
    assert why == f"state inconsistent: exist: shape ({n + 1}, 2), declared ({n}, 2)"
    assert fresh.pipeline is None


def test_a_snapshot_of_the_format_before_is_refused_naming_both_versions(tmp_path):
    blob = gzip.decompress((DATA / "state_b062918.npz.gz").read_bytes())
    store = StateStore(tmp_path / "s", "main", max_age=1e12, id_horizon=60)
    with pytest.raises(StateRejected) as e:
        store.check(blob)
    assert e.value.reason == "format version"
    assert str(e.value) == (
        "format version: snapshot container format 2: this version of skyfuse reads format 3"
    )
    (tmp_path / "s" / "state.npz").write_bytes(blob)  # a state directory left by b062918
    assert store.load() == (None, f"saved state refused ({e.value})")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_truncated_or_flipped_blobs_never_raise(data, scenario, tmp_path_factory):
    if not hasattr(test_truncated_or_flipped_blobs_never_raise, "blob"):
        tmp = tmp_path_factory.mktemp("blob")
        test_truncated_or_flipped_blobs_never_raise.blob = _state_of_a_run(scenario, tmp)[1]
    blob = bytearray(test_truncated_or_flipped_blobs_never_raise.blob)
    cut = data.draw(st.integers(0, len(blob)))
    flips = data.draw(st.lists(st.tuples(st.integers(0, len(blob) - 1), st.integers(0, 255))))
    for i, v in flips:
        blob[i] = v
    store = StateStore(tmp_path_factory.mktemp("s"), "main", max_age=60, id_horizon=60)
    try:
        store.check(bytes(blob[:cut]))
    except StateRejected as e:
        assert e.reason in REASONS


def test_the_state_serialises_after_every_cycle(tmp_path):
    """The state serialises at any instant (pending track rows, registration buffers …),
    not only at one chosen instant."""
    sc = build_scenario("regional", seed=1, duration=20.0, targets=25, radars=4)
    events = list(Simulator(sc, seed=1).run(truth=False))
    batches = sorted((e.message for e in events if e.kind == "plots"), key=lambda b: b.time_end)
    core = _core(sc.sites, TrackerConfig())
    store = StateStore(tmp_path / "s", "main", max_age=60, id_horizon=60)
    kinds = set()
    for b in batches:
        core.on_plots(b, 0.0)
        for o in core.poll(flush=True):
            kinds |= {e.kind for e in o.events}
        store.check(store.serialise(capture(core), 1))  # raises if anything is refused
    assert "confirmed" in kinds  # the run went through track events
