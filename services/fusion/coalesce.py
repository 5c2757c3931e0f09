"""Coalescing: consecutive sector batches of one radar applied as one tracker step.

A rotating radar reports its revolution in sector batches (``PlotBatch.sector_start``,
``sector_width``, swept from ``time_start`` to ``time_end``). When the fusion service is
behind, several contiguous sectors of one radar are ready at once; the overload policy
(:mod:`~skyfuse.services.fusion.overload`) decides how many of them may be concatenated
into one batch covering their union (at most ``coalesce_max_deg`` degrees of azimuth),
which goes through the tracker as one step. The tracker's work per step is mostly fixed
(the tracks of the swept coverage are predicted, gated and managed once), so the work
per plot falls with the batch size: this is how the service's throughput rises with its
load.

What the tracker sees is what a radar reporting fewer, wider sectors would send: the
same plots, the swept sector the union of the members' sectors, swept from the first
member's ``time_start`` to the last member's ``time_end`` (each track is still predicted
to the time the beam crossed it, :mod:`fusion.tracker.coverage`). A simulated radar of 16
sectors coalesced by fours gives exactly the tracks of the same radar simulated with 4
sectors (tested).

Rules (:func:`plan`): a batch joins the open run of its radar when it continues it —
its sector starts where the run's last sector ends (within ``ANGLE_TOL``), it starts
after the run's last batch started (an ASTERIX reader widens a sector's times to its
plots', so consecutive sectors may overlap a little) and no later than one of that
batch's sweep durations after it ended (no missing sector), it carries the same plot
columns and the same numbering epoch, and the run stays within the width limit (never a
whole revolution twice: one plot per target and radar per step). Late batches (behind
the service time) are never coalesced. A run takes the place of its *last* member in the
time order, so the steps stay in order of their ``time_end``; the other radars' batches
that fell between its members are applied before it (their tracks take the coalesced plots older
than their state through the out-of-sequence update, as for any overlapping sweep).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from skyfuse.schemas import PlotBatch
from skyfuse.schemas.plots import OPTIONAL_PLOT_COLUMNS

ANGLE_TOL = 1e-6
"""Two sectors are contiguous when one starts within this many radians of the other's end."""

TWO_PI = 2.0 * math.pi


def columns(batch: PlotBatch) -> tuple[str, ...]:
    """The optional plot columns the batch carries."""
    return tuple(k for k in OPTIONAL_PLOT_COLUMNS if getattr(batch, k) is not None)


def continues(last: PlotBatch, nxt: PlotBatch, width: float, max_width: float) -> bool:
    """Whether ``nxt`` continues a run of batches ending with ``last`` (the run's azimuth
    width so far ``width``, rad) without passing ``max_width`` (see the module docstring)."""
    if nxt.radar_id != last.radar_id or nxt.epoch != last.epoch:
        return False
    if width + nxt.sector_width > max_width + ANGLE_TOL:
        return False
    gap = (nxt.sector_start - (last.sector_start + last.sector_width)) % TWO_PI
    if min(gap, TWO_PI - gap) > ANGLE_TOL:
        return False
    sweep = last.time_end - last.time_start
    if not last.time_start < nxt.time_start <= last.time_end + sweep:
        return False
    return columns(nxt) == columns(last)


def plan(
    batches: Sequence[PlotBatch],
    mergeable: Sequence[bool],
    max_width: float,
    sources: Sequence[object] | None = None,
    max_members: int | None = None,
) -> list[list[int]]:
    """The runs (lists of indexes into ``batches``, in order) to apply as one step each,
    in the order to apply them: each run at the place of its last member. ``batches`` are
    in application order; ``mergeable[i]`` False keeps batch i on its own; ``sources[i]``
    (optional): what batch i is converted with (its radar site), the same in a run;
    ``max_members``: at most this many batches in a run (the overload policy's choice,
    :mod:`~skyfuse.services.fusion.overload`; default: only the width bounds a run)."""
    runs: list[list[int]] = []
    open_run: dict[str, tuple[list[int], float]] = {}
    for i, b in enumerate(batches):
        if not mergeable[i]:
            runs.append([i])
            continue
        cur = open_run.get(b.radar_id)
        if cur is not None:
            run, width = cur
            j = run[-1]
            same = sources is None or sources[j] is sources[i]
            room = max_members is None or len(run) < max_members
            if same and room and continues(batches[j], b, width, max_width):
                run.append(i)
                open_run[b.radar_id] = (run, width + b.sector_width)
                continue
        run = [i]
        runs.append(run)
        open_run[b.radar_id] = (run, b.sector_width)
    return sorted(runs, key=lambda r: r[-1])


def concat(batches: Sequence[PlotBatch], cols: tuple[str, ...], sector_width: float) -> PlotBatch:
    """The plots of several validated batches of one radar as one batch, in order: the
    first batch's numbering and sector start, the last one's ``seq``, ``sector_width``
    as given (the union of contiguous sectors; for a concatenation used only to convert
    the plots, any value), swept from the earliest ``time_start`` to the latest
    ``time_end``. Built without validation (every member was validated)."""
    first = batches[0]
    data = {k: [v for b in batches for v in getattr(b, k)] for k in ("time", *cols)}
    return PlotBatch.model_construct(
        radar_id=first.radar_id,
        scan=first.scan,
        seq=batches[-1].seq,
        epoch=first.epoch,
        sector_start=first.sector_start,
        sector_width=sector_width,
        time_start=min(b.time_start for b in batches),
        time_end=max(b.time_end for b in batches),
        **{k: None for k in OPTIONAL_PLOT_COLUMNS if k not in cols},
        **data,
    )


def coalesced(batches: Sequence[PlotBatch]) -> PlotBatch:
    """The batch a run of :func:`plan` is applied as (a run of one: that batch)."""
    if len(batches) == 1:
        return batches[0]
    width = min(TWO_PI, sum(b.sector_width for b in batches))
    return concat(batches, columns(batches[0]), width)
