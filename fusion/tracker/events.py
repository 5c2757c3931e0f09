"""The tracker's event record: what happened to a track in a step, for the event feed.

Life-cycle kinds (:mod:`.tracker`, :mod:`.management`): ``confirmed``, ``terminated``,
``merged`` (``track_id`` removed as a duplicate of ``other_track_id``). Identity kinds
(:mod:`.identity`): ``identity_changed``, ``identity_conflict``, ``emergency``, ``spi``,
with the attribute concerned and its values as text (the Mode-3/A code in octal, the
Mode-S address in hexadecimal, the callsign).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class TrackEventRecord:
    """An event of track ``track_id`` at ``time_ns`` (see the module docstring); its
    existence then, a reason in words, and for the identity kinds the ``attribute``
    (``mode_3a``, ``mode_s``, ``callsign``, ``spi``), the ``value`` seen or adopted and
    the ``previous`` one shown ("" when none)."""

    time_ns: int
    kind: str
    track_id: int
    existence: float
    other_track_id: int | None = None
    reason: str = ""
    attribute: str = ""
    value: str = ""
    previous: str = ""
