"""The identity part of the tracker (fusion/tracker/identity.py): the rules on hand-built
sequences of replies (a garbled or unvalidated code never wins, a change needs two
sightings in a row, conflicts within the window, emergencies, SPI, flight level, late
plots, downlinked registers), callsign packing against the CAT048 encoder, the wiring
through ``Tracker.step`` (only plots of weight above one half), and that attribution
never changes the kinematics."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig
from skyfuse.fusion.tracker.identity import (
    CALLSIGN,
    DOWNLINK_NAMES,
    MODE_3A,
    MODE_S,
    REGISTERS,
    pack_callsigns,
    plot_identity,
    unpack_callsigns,
)
from skyfuse.fusion.tracker.tracker import tracker_from_snapshot
from skyfuse.schemas.identity import EMERGENCY_CODES
from skyfuse.services.asterix.cat048 import decode_callsign, encode_callsign

S = 10**9
T0 = 1_700_000_000 * S
A, B = 0o1234, 0o4321
S1, S2, S3 = 0x4CA123, 0x3C4567, 0x484F6D


def replies(**cols) -> object:
    """The PlotIdentity of one plot with the given columns (PlotBatch.column style)."""
    arrays = {}
    for name, v in cols.items():
        if name == "callsign":
            arrays[name] = np.array([v], dtype="<U8")
        elif isinstance(v, bool):
            arrays[name] = np.array([v])
        elif isinstance(v, int):
            arrays[name] = np.array([v], np.int64)
        else:
            arrays[name] = np.array([v], float)
    return plot_identity(arrays.get)


def tracker(**kw) -> Tracker:
    return Tracker(TrackerConfig(**{"motion": "cv", "tracker": "ipda", **kw}))


def one_track(confirmed=True, **kw):
    tr = tracker(**kw)
    tr.add_track([0, 100, 0, 0], np.eye(4) * 100.0, T0, existence=0.99, confirmed=confirmed)
    return tr


def see(tr: Tracker, k: float, **cols) -> list:
    """The track (row 0) confirmed by one plot at T0 + k s; returns the events raised."""
    tr.identity.observe(replies(**cols), np.array([0]), np.array([0]),
                        np.array([T0 + round(k * S)]))  # fmt: skip
    events: list = []
    tr.identity.flush(events, {})
    return events


def shown(tr: Tracker, attribute: int) -> int:
    return int(tr.tracks.ident_code[0, attribute])


def test_callsigns_pack_as_the_cat048_encoder_and_back():
    valid = ["AFR1234", "A", "RYR12AB", "N 123", "12345678", "BAW1", "Z9"]
    packed = pack_callsigns(np.array(valid))
    assert packed.tolist() == [encode_callsign(t) for t in valid]
    assert list(unpack_callsigns(packed)) == [decode_callsign(int(p)) for p in packed] == valid
    assert pack_callsigns(np.array(["", "afr1", "AF#1", "AB-1"])).tolist() == [-1] * 4


def test_a_code_is_adopted_at_its_second_sighting():
    tr = one_track()
    see(tr, 1, mode_3a=A)
    assert shown(tr, MODE_3A) == -1
    assert see(tr, 2, mode_3a=A) == []  # the first code: no change event
    assert shown(tr, MODE_3A) == A and tr.tracks.ident_time[0, MODE_3A] == T0 + 2 * S
    see(tr, 3, mode_3a=A)
    assert tr.tracks.ident_time[0, MODE_3A] == T0 + 3 * S


def test_identity_confirm_one_adopts_at_once():
    tr = one_track(identity_confirm=1)
    see(tr, 1, mode_s=S1)
    assert shown(tr, MODE_S) == S1


@pytest.mark.parametrize("flag", ["mode_3a_garbled", "mode_3a_not_validated", "mode_3a_smoothed"])
def test_a_garbled_or_unvalidated_code_never_replaces_a_validated_one(flag):
    tr = one_track()
    see(tr, 1, mode_3a=A)
    see(tr, 2, mode_3a=A)
    for k in range(3, 13):
        assert see(tr, k, mode_3a=B, **{flag: True}) == []
    assert shown(tr, MODE_3A) == A
    assert tr.tracks.ident_time[0, MODE_3A] == T0 + 2 * S  # nor do they confirm it
    see(tr, 13, mode_3a=A, **{flag: True})
    assert tr.tracks.ident_time[0, MODE_3A] == T0 + 2 * S


def test_a_squawk_change_needs_two_sightings_in_a_row():
    tr = one_track(identity_change_hold=30.0)
    see(tr, 1, mode_3a=A)
    see(tr, 2, mode_3a=A)
    for k, code in enumerate((B, A, B, A, B, A), start=3):
        assert see(tr, k, mode_3a=code) == []
        assert shown(tr, MODE_3A) == A
    see(tr, 9, mode_3a=B)
    (e,) = see(tr, 10, mode_3a=B)
    assert shown(tr, MODE_3A) == B
    assert (e.kind, e.attribute, e.value, e.previous) == ("identity_changed", "mode_3a", "4321",
                                                         "1234")  # fmt: skip
    assert e.time_ns == T0 + 10 * S and e.track_id == tr.ids[0]
    assert tr.identity.output(T0 + 40 * S).mode_3a_changed[0]  # CH within the hold
    assert not tr.identity.output(T0 + 41 * S).mode_3a_changed[0]


def test_a_second_mode_s_address_within_the_window_is_a_conflict():
    tr = one_track(identity_conflict_window=60.0)
    see(tr, 0, mode_s=S1, callsign="AFR12")
    see(tr, 4, mode_s=S1, callsign="AFR12")
    events = see(tr, 8, mode_s=S2, callsign="BAW3")
    assert [(e.kind, e.attribute, e.value, e.previous) for e in events] == [
        ("identity_conflict", "mode_s", "3C4567", "4CA123"),
        ("identity_conflict", "callsign", "BAW3", "AFR12"),
    ]
    assert shown(tr, MODE_S) == S1  # one stray reply does not change the identity
    events = see(tr, 12, mode_s=S2, callsign="BAW3")
    changed = [("identity_changed", "mode_s"), ("identity_changed", "callsign")]
    assert [(e.kind, e.attribute) for e in events] == changed
    assert shown(tr, MODE_S) == S2 and shown(tr, CALLSIGN) == pack_callsigns(["BAW3"])[0]
    assert see(tr, 16, mode_s=S3) == []  # at most one conflict per window
    see(tr, 70, mode_s=S2)
    assert [e.kind for e in see(tr, 72, mode_s=S1)] == ["identity_conflict"]  # 64 s later


def test_another_address_after_the_window_is_a_change_not_a_conflict():
    tr = one_track(identity_conflict_window=60.0)
    see(tr, 0, mode_s=S1)
    see(tr, 4, mode_s=S1)
    assert see(tr, 65, mode_s=S2) == []
    assert [e.kind for e in see(tr, 69, mode_s=S2)] == ["identity_changed"]


def test_a_mode_3a_change_is_never_a_conflict():
    tr = one_track()
    see(tr, 0, mode_3a=A)
    see(tr, 4, mode_3a=A)
    assert see(tr, 8, mode_3a=B) == []


def test_tentative_tracks_raise_no_events_and_confirmation_raises_the_standing_ones():
    tr = one_track(confirmed=False)
    see(tr, 0, mode_s=S1, mode_3a=A, spi=True)
    see(tr, 4, mode_s=S1, mode_3a=A)
    assert see(tr, 8, mode_s=S2, mode_3a=0o7700, spi=True) == []
    assert see(tr, 12, mode_s=S2, mode_3a=0o7700, spi=True) == []
    assert shown(tr, MODE_3A) == 0o7700
    tr.identity.confirmed(np.array([0]), T0 + 13 * S)
    events: list = []
    tr.identity.flush(events, stats := {})
    assert [(e.kind, e.value) for e in events] == [("emergency", "7700"), ("spi", "")]
    assert stats == {"emergencies": 1, "spi_raised": 1}


@pytest.mark.parametrize("code", [0o7500, 0o7600, 0o7700])
def test_an_emergency_code_raises_its_event_once(code):
    tr = one_track()
    see(tr, 0, mode_3a=A)
    see(tr, 4, mode_3a=A)
    assert see(tr, 8, mode_3a=code) == []
    events = see(tr, 12, mode_3a=code)
    assert [e.kind for e in events] == ["identity_changed", "emergency"]
    assert events[1].value == f"{code:04o}"
    assert EMERGENCY_CODES[code].replace("_", " ") in events[1].reason
    assert see(tr, 16, mode_3a=code) == []


def test_spi_raises_an_event_when_it_is_set():
    tr = one_track()
    assert see(tr, 0, mode_3a=A, spi=False) == []
    assert [e.kind for e in see(tr, 4, mode_3a=A, spi=True)] == ["spi"]
    assert see(tr, 8, mode_3a=A, spi=True) == []
    assert tr.tracks.spi[0]
    see(tr, 12, mode_3a=A)
    assert not tr.tracks.spi[0]


def test_flight_level_only_from_valid_replies():
    tr = one_track()
    see(tr, 0, flight_level=350.0)
    assert tr.tracks.flight_level[0] == 350.0
    see(tr, 4, flight_level=120.0, flight_level_garbled=True)
    see(tr, 8, flight_level=130.0, flight_level_not_validated=True)
    assert tr.tracks.flight_level[0] == 350.0 and tr.tracks.flight_level_time[0] == T0
    see(tr, 12, flight_level=349.75)
    assert tr.tracks.flight_level[0] == 349.75


def test_a_late_plot_never_overrides_newer_evidence():
    tr = one_track()
    see(tr, 10, mode_s=S1, flight_level=200.0)
    see(tr, 14, mode_s=S1, flight_level=210.0)
    see(tr, 12, mode_s=S2, flight_level=205.0)  # older than both confirmations
    assert tr.tracks.ident_cand[0, MODE_S] == -1 and tr.tracks.flight_level[0] == 210.0
    assert tr.tracks.reply_time[0].tolist() == [T0 + 14 * S] * 2


def test_downlinked_parameters_go_by_register_with_their_time():
    tr = one_track()
    see(tr, 0, mode_s=S1, selected_altitude_mcp=330.0, ground_speed=230.0, true_track=1.0)
    see(tr, 4, mode_s=S1, ground_speed=231.0)
    dl, when = tr.tracks.downlink[0], tr.tracks.downlink_time[0]
    i = {n: j for j, n in enumerate(DOWNLINK_NAMES)}
    assert dl[i["selected_altitude_mcp"]] == 330.0 and when[REGISTERS.index("4,0")] == T0
    assert dl[i["ground_speed"]] == 231.0 and when[REGISTERS.index("5,0")] == T0 + 4 * S
    assert np.isnan(dl[i["true_track"]])  # the last 5,0 report had no track angle
    assert when[REGISTERS.index("6,0")] == -1


# ------------------------------------------------------------------ through Tracker.step
def straight_scene(seed=3, clutter=30, codes=True, scans=25):
    """Two aircraft crossing at 2 km/s apart plus clutter, one plot each per scan, with
    their codes (and a code flipping garbled reply) when ``codes``."""
    rng = np.random.default_rng(seed)
    batches = []
    for k in range(1, scans + 1):
        p = np.array([[-3000 + 200.0 * k, 0.0], [0.0, -3000 + 180.0 * k]])
        z = np.vstack([p + rng.normal(0, 20, (2, 2)), rng.uniform(-6000, 6000, (clutter, 2))])
        ident = None
        if codes:
            m = len(z)
            col = {"mode_3a": np.r_[A, B, np.full(m - 2, -1)].astype(np.int64),
                   "mode_s": np.r_[S1, S2, np.full(m - 2, -1)].astype(np.int64),
                   "callsign": np.array(["AFR12", "BAW3"] + [""] * (m - 2), "<U8"),
                   "mode_3a_garbled": np.r_[k % 5 == 0, False, np.zeros(m - 2, bool)]}  # fmt: skip
            col["mode_3a"][0] ^= 0o7 if k % 5 == 0 else 0  # garbled: a wrong code
            ident = plot_identity(col.get)
        batches.append(MeasurementBatch(T0 + k * 4 * S, "r", z, 400.0 * np.eye(2), 0.95,
                                        clutter / 12000.0**2, identity=ident))  # fmt: skip
    return batches


def test_the_tracks_show_their_aircraft_identity_after_tracker_steps():
    tr = tracker(tracker="lmits", motion="imm-cv-ct")
    for b in straight_scene():
        out = tr.step(b)
    conf = np.flatnonzero(out.confirmed)
    assert len(conf) == 2
    codes = out.identity.codes[conf]
    assert sorted(map(tuple, codes.tolist())) == sorted(
        [(A, S1, pack_callsigns(["AFR12"])[0]), (B, S2, pack_callsigns(["BAW3"])[0])]
    )
    assert not any(e.kind.startswith("identity") for e in out.events)


@pytest.mark.parametrize("kind", ["ipda", "lmits", "jipda", "gnn"])
def test_identity_never_changes_the_kinematics(kind):
    runs = []
    for identity in (False, True):
        tr = tracker(tracker=kind, identity=identity)
        outs = [tr.step(b) for b in straight_scene(seed=5, clutter=60)]
        runs.append(outs)
    for a, b in zip(*runs):
        assert np.array_equal(a.ids, b.ids) and np.array_equal(a.confirmed, b.confirmed)
        assert np.array_equal(a.states, b.states) and np.array_equal(a.covariances, b.covariances)
        assert np.array_equal(a.existence, b.existence)
        assert np.array_equal(a.assigned_plot, b.assigned_plot)
    assert runs[0][-1].identity is None and runs[1][-1].identity is not None


def test_a_batch_without_secondary_data_leaves_the_identity_empty():
    tr = tracker(tracker="lmits")
    for b in straight_scene(codes=False):
        out = tr.step(b)
    assert out.confirmed.sum() == 2
    assert (out.identity.codes == -1).all() and np.isnan(out.identity.flight_level).all()
    assert (out.identity.revision == 0).all()


def test_a_snapshot_keeps_the_identity_columns():
    scene = straight_scene()
    tr = tracker(tracker="lmits", motion="imm-cv-ct")
    for b in scene[:12]:
        tr.step(b)
    copy = tracker_from_snapshot(tr.to_snapshot())
    for name in ("ident_code", "ident_time", "ident_cand", "ident_seen", "ident_changed",
                 "ident_conflict", "flight_level", "spi", "downlink", "reply_time"):  # fmt: skip
        assert np.array_equal(getattr(copy.tracks, name), getattr(tr.tracks, name), equal_nan=True)
    for b in scene[12:]:
        x, y = tr.step(b), copy.step(b)
        assert np.array_equal(x.identity.codes, y.identity.codes)
        assert np.array_equal(x.states, y.states)
