"""Track retention table ([thesis] §7.2.1).

At scan ``k_start`` (14) the confirmed true track of each target is identified, in every
Monte Carlo run; each such (run, target) pair is a **case** (nCases). At scan ``k_end``
(38 of 40) the case's track is

* **OK**: present and labelled true for the *same* target;
* **switched**: present and labelled true for *another* target;
* **lost**: labelled false or no longer present (terminated or deleted);

so nOK + nSwitched + nLost = nCases (reported as percentages of nCases). **merged** is the
number of case tracks deleted by merging / duplicate removal in (k_start, k_end] (a count,
a subset of the lost ones, [thesis] §7.2.1). If a target has several confirmed true tracks at
``k_start`` (duplicates), the case takes the one with the highest existence probability
ψ (``TrackHistory.existence``), or the smallest track id (the oldest) when ψ is not given.
CPU seconds are measured by the caller and carried in the row.

``RetentionCounts`` add up over runs and batches; ``row`` gives the JSON/Markdown row
with keys ``tracker``, ``depth``, ``nCases``, ``nOK``, ``nSwitched``, ``nLost`` (percent),
``merged`` (count), ``cpu_s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .history import TrackHistory, joint_keys

ROW_KEYS = ("tracker", "depth", "nCases", "nOK", "nSwitched", "nLost", "merged", "cpu_s")


@dataclass(frozen=True)
class RetentionCounts:
    """Counts of cases (see module docstring); ``cpu_s`` in seconds. Add with ``+``."""

    n_cases: int = 0
    n_ok: int = 0
    n_switched: int = 0
    n_lost: int = 0
    merged: int = 0
    cpu_s: float = 0.0

    def __add__(self, other: RetentionCounts) -> RetentionCounts:
        return RetentionCounts(
            self.n_cases + other.n_cases,
            self.n_ok + other.n_ok,
            self.n_switched + other.n_switched,
            self.n_lost + other.n_lost,
            self.merged + other.merged,
            self.cpu_s + other.cpu_s,
        )

    def _percent(self, n: int) -> float | None:
        return 100.0 * n / self.n_cases if self.n_cases else None

    def row(self, tracker: str, depth: int) -> dict[str, object]:
        """One table row: percentages for nOK/nSwitched/nLost (None when nCases = 0)."""
        return {
            "tracker": tracker,
            "depth": int(depth),
            "nCases": int(self.n_cases),
            "nOK": self._percent(self.n_ok),
            "nSwitched": self._percent(self.n_switched),
            "nLost": self._percent(self.n_lost),
            "merged": int(self.merged),
            "cpu_s": float(self.cpu_s),
        }


def retention_counts(
    tracks: TrackHistory,
    merged_run: np.ndarray,
    merged_track_id: np.ndarray,
    merged_scan: np.ndarray,
    k_start: int = 14,
    k_end: int = 38,
    cpu_s: float = 0.0,
) -> RetentionCounts:
    """Retention counts of the runs in ``tracks``.

    ``merged_run``, ``merged_track_id``, ``merged_scan`` (q,) list the tracks deleted by
    merging / duplicate removal and the scan of deletion. ``k_start < k_end`` are scan
    numbers in the history's numbering."""
    if not k_start < k_end:
        raise ValueError(f"k_start = {k_start}, k_end = {k_end}: need k_start < k_end")
    mr, mt, ms = (
        np.asarray(a, dtype=np.int64).reshape(-1)
        for a in (merged_run, merged_track_id, merged_scan)
    )
    if not (len(mr) == len(mt) == len(ms)):
        raise ValueError(
            f"merged_run/merged_track_id/merged_scan: lengths {len(mr)}, {len(mt)}, {len(ms)}: "
            "must be equal"
        )
    at_start = np.flatnonzero((tracks.scan == k_start) & tracks.confirmed_true)
    # One track per (run, target): highest ψ first (NaN last), then the smallest id.
    psi = np.nan_to_num(tracks.existence[at_start], nan=-np.inf)
    order = np.lexsort(
        (tracks.track_id[at_start], -psi, tracks.label[at_start], tracks.run[at_start])
    )
    rows = at_start[order]
    pair_key = joint_keys((tracks.run[rows], tracks.label[rows]))[0]
    _, first = np.unique(pair_key, return_index=True)
    cases = rows[first]
    run, target, tid = tracks.run[cases], tracks.label[cases], tracks.track_id[cases]

    at_end = np.flatnonzero(tracks.scan == k_end)
    case_k, end_k, merge_k = joint_keys(
        (run, tid), (tracks.run[at_end], tracks.track_id[at_end]), (mr, mt)
    )
    end_order = np.argsort(end_k, kind="stable")
    pos = np.searchsorted(end_k[end_order], case_k)
    present = pos < len(end_k)
    present[present] = end_k[end_order][pos[present]] == case_k[present]
    end_label = np.full(len(cases), -1, dtype=np.int64)
    end_label[present] = tracks.label[at_end][end_order][pos[present]]
    ok = present & (end_label == target)
    switched = present & (end_label >= 0) & (end_label != target)
    in_window = (ms > k_start) & (ms <= k_end)
    merged = np.isin(case_k, merge_k[in_window])
    return RetentionCounts(
        n_cases=len(cases),
        n_ok=int(ok.sum()),
        n_switched=int(switched.sum()),
        n_lost=int(len(cases) - ok.sum() - switched.sum()),
        merged=int(merged.sum()),
        cpu_s=float(cpu_s),
    )


def retention_markdown(rows: list[dict[str, object]]) -> str:
    """A Markdown table of ``RetentionCounts.row`` dicts (percentages to one decimal)."""

    def fmt(key: str, v: object) -> str:
        if v is None or (isinstance(v, float) and math.isnan(v)):
            return "–"
        if key in ("nOK", "nSwitched", "nLost"):
            return f"{v:.1f}"
        if key == "cpu_s":
            return f"{v:.2f}"
        return str(v)

    head = "| " + " | ".join(ROW_KEYS) + " |"
    rule = "|" + "|".join("---" if k == "tracker" else "---:" for k in ROW_KEYS) + "|"
    body = ["| " + " | ".join(fmt(k, r[k]) for k in ROW_KEYS) + " |" for r in rows]
    return "\n".join([head, rule, *body]) + "\n"
