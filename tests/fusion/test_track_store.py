"""The columnar table of the track store (``fusion/tracker/store.py``) against plain
arrays grown by concatenation and cut by boolean masks (what the tracker did before),
over random appends and removals past its capacity; its hooks; and the checks of its
snapshots."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from skyfuse.fusion.tracker.store import Column, ColumnGroup, NewTracks, Table
from skyfuse.schemas.snapshot import SnapshotError


def _groups(log: list):
    core = ColumnGroup(
        "core",
        (Column("ids", np.int64), Column("t", np.int64), Column("flag", bool, fill=False),
         Column("h", np.float64, fill=np.nan)),
        init=lambda new: {"t": new.t},
    )  # fmt: skip
    dens = ColumnGroup(
        "density",
        (Column("x", np.float64, (2,)), Column("P", np.float64, (2, 2))),
        init=lambda new: {"x": new.x, "P": new.P},
        appended=lambda rows, new: log.append(("appended", rows.tolist())),
        kept=lambda mask: log.append(("kept", mask.tolist())),
    )
    return core, dens


def test_rows_follow_concatenation_and_masks():
    rng = np.random.default_rng(3)
    log: list = []
    table = Table(*_groups(log))
    ref = {"ids": np.zeros(0, np.int64), "t": np.zeros(0, np.int64), "flag": np.zeros(0, bool),
           "h": np.zeros(0), "x": np.zeros((0, 2)), "P": np.zeros((0, 2, 2))}  # fmt: skip
    next_id = 1
    for _ in range(200):
        if rng.random() < 0.5 or not len(table):
            k = int(rng.integers(1, 40))
            new = NewTracks(rng.normal(size=(k, 2)), rng.normal(size=(k, 2, 2)),
                            rng.integers(0, 10**9, k))  # fmt: skip
            ids = next_id + np.arange(k)
            next_id += k
            rows = table.append(new, ids=ids)
            assert log[-1] == ("appended", rows.tolist())
            add = {"ids": ids, "t": new.t, "flag": np.zeros(k, bool), "h": np.full(k, np.nan),
                   "x": new.x, "P": new.P}  # fmt: skip
            ref = {n: np.concatenate([ref[n], add[n]]) for n in ref}
        else:
            mask = rng.random(len(table)) > 0.3
            table.keep(mask)
            assert log[-1] == ("kept", mask.tolist())
            ref = {n: a[mask] for n, a in ref.items()}
        rows = rng.random(len(table)) < 0.1
        table.flag[rows] = True  # in place, as the tracker writes
        table.h[rows] = 7.0
        ref["flag"][rows], ref["h"][rows] = True, 7.0
        assert len(table) == len(ref["ids"])
        for name, a in ref.items():
            np.testing.assert_array_equal(getattr(table, name), a)
    assert next_id > 64 * 4  # well past the initial capacity
    got = table.take(np.array([0, 2]), ("ids", "x"))
    np.testing.assert_array_equal(got["x"], ref["x"][[0, 2]])


def test_declarations_and_values_are_checked():
    table = Table(*_groups([]))
    with pytest.raises(ValueError, match="taken"):
        table.declare(ColumnGroup("other", (Column("x", np.float64),)))
    with pytest.raises(ValueError, match="taken"):
        table.declare(ColumnGroup("other", (Column("keep", np.float64),)))
    with pytest.raises(AttributeError, match="write into it"):
        table.h = np.zeros(0)
    new = NewTracks(np.zeros((2, 2)), np.zeros((2, 2, 2)), np.zeros(2, np.int64))
    with pytest.raises(ValueError, match="column 'ids': no value"):
        table.append(new)
    with pytest.raises(ValueError, match=r"column 'ids': \(3,\) for 2 rows"):
        table.append(new, ids=np.arange(3))
    table.append(new, ids=np.arange(2))
    with pytest.raises(ValueError, match="before the first row"):
        table.declare(ColumnGroup("late", (Column("y", np.float64),)))


def test_snapshots_hold_the_declared_columns_only():
    table = Table(*_groups([]))
    table.append(NewTracks(np.ones((3, 2)), np.ones((3, 2, 2)), np.arange(3)), ids=np.arange(3))
    snap = table.to_snapshot()
    again = Table(*_groups([]))
    again.from_snapshot({"rows": 3, "columns": {k: v.copy() for k, v in snap["columns"].items()}})
    for name in table.names:
        np.testing.assert_array_equal(getattr(again, name), getattr(table, name))
    again.append(NewTracks(np.ones((1, 2)), np.ones((1, 2, 2)), np.arange(1)), ids=[9])
    assert again.ids.tolist() == [0, 1, 2, 9]
    cols = snap["columns"]
    for columns, match in (
        ({**cols, "x": cols["x"][:2]}, r"x: shape \(2, 2\), declared \(3, 2\)"),
        ({**cols, "t": cols["t"].astype(float)}, "t: dtype float64, declared int64"),
        ({k: v for k, v in cols.items() if k != "P"}, "P: NoneType where an array"),
        ({**cols, "y": cols["h"]}, "undeclared column 'y'"),
    ):
        with pytest.raises(SnapshotError, match=match):
            Table(*_groups([])).from_snapshot({"rows": 3, "columns": columns})
    with pytest.raises(SnapshotError, match="rows"):
        Table(*_groups([])).from_snapshot({"rows": -1, "columns": cols})


def test_a_pickled_table_writes_into_its_columns():
    """After pickling (the Monte Carlo workers), a column written in place keeps the value
    through the next append: the views are made again, not copied."""
    table = pickle.loads(pickle.dumps(_table_with_rows()))
    table.h[:] = 5.0
    table.append(NewTracks(np.ones((1, 2)), np.ones((1, 2, 2)), np.arange(1)), ids=[7])
    assert table.h[:3].tolist() == [5.0] * 3 and np.isnan(table.h[3])


def _table_with_rows() -> Table:
    table = Table(*_groups_picklable())
    table.append(NewTracks(np.ones((3, 2)), np.ones((3, 2, 2)), np.arange(3)), ids=np.arange(3))
    return table


def _init_t(new):
    return {"t": new.t, "x": new.x, "P": new.P}


def _groups_picklable():
    return (
        ColumnGroup("core", (Column("ids", np.int64), Column("t", np.int64),
                             Column("h", np.float64, fill=np.nan)), init=_init_t),
        ColumnGroup("density", (Column("x", np.float64, (2,)), Column("P", np.float64, (2, 2)))),
    )  # fmt: skip
