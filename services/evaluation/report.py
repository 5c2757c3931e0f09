"""The JSON summary of an offline run as the commands print and write it.

``skyfuse track`` and ``skyfuse eval`` print one line (:func:`headline`: the key figures
of the summary of :func:`~skyfuse.services.evaluation.offline.run_offline`) and, with
``--json FILE``, write the whole summary (:func:`write_summary`; ``--json`` alone or
``--json -`` prints it to stdout instead of the line).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

STDOUT = "-"
_TR = "labels_by_traffic"

_HEADLINE = (
    ("batches", ("batches",)),
    ("plots_processed", ("plots_processed",)),
    ("aircraft", ("labels", "aircraft")),
    ("aircraft_with_confirmed_track", ("labels", "aircraft_with_confirmed_track")),
    ("completeness", ("labels", "completeness")),
    ("confirmed_tracks", ("labels", "confirmed_tracks")),
    ("confirmed_false_tracks", ("labels", "confirmed_false_tracks")),
    ("confirmed_false_tracks_per_hour", ("labels", "confirmed_false_tracks_per_hour")),
    ("truth_coverage", ("truth", "coverage")),
    ("position_rmse_m", ("truth", "position_rmse_m")),
    ("gospa_mean_m", ("truth", "gospa", "mean_m")),
    ("identity_mode_s_correct", ("identity", "mode_s_correct")),
    ("identity_callsign_within_2_scans", ("identity", "callsign_within_2_scans")),
    ("identity_flight_level_within_1", ("identity", "flight_level_within_1")),
    ("identity_conflicts", ("identity", "conflicts")),
    ("identity_conflicts_per_hour", ("identity", "conflicts_per_hour")),
    ("plots_near_radar", ("plots_near_radar",)),
    ("airborne_track_ids_per_aircraft", (_TR, "airborne", "track_ids_per_aircraft")),
    ("airborne_id_changes_per_aircraft", (_TR, "airborne", "id_changes_per_aircraft")),
    ("surface_track_ids_per_aircraft", (_TR, "surface", "track_ids_per_aircraft")),
    ("all_track_ids_per_aircraft", (_TR, "all", "track_ids_per_aircraft")),
    ("duplicates_per_aircraft", ("registration_vs_truth", "duplicates", "duplicates_per_aircraft")),
    ("registration_off_rmse_m", ("registration_off", "position_rmse_m")),
    ("registration_off_duplicates_per_aircraft",
     ("registration_off", "duplicates", "duplicates_per_aircraft")),
    ("reference_surface_pou", ("reference", "surface", "probability_of_update")),
    ("reference_surface_rms_m", ("reference", "surface", "position", "rms_m")),
    ("reference_airborne_pou", ("reference", "airborne", "probability_of_update")),
    ("reference_airborne_rms_m", ("reference", "airborne", "position", "rms_m")),
    ("reference_track_ids_per_aircraft", ("reference", "all", "track_ids_per_aircraft")),
    ("reference_false_tracks", ("reference", "all", "false_tracks")),
    ("wall_s", ("timing", "wall_s")),
)  # fmt: skip


def _get(d: dict, path: tuple[str, ...]):
    for k in path:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


def headline(summary: dict) -> dict:
    """The key figures of a summary, flat, in a fixed order (absent ones left out)."""
    out = {}
    for name, path in _HEADLINE:
        v = _get(summary, path)
        if v is not None:
            out[name] = v
    return out


def write_summary(summary: dict, json_path: str | Path | None) -> None:
    """Print the headline; with ``json_path`` write the whole summary there (``-``:
    print it to stdout instead of the headline)."""
    text = json.dumps(summary, indent=1, default=str)
    if json_path is not None and str(json_path) == STDOUT:
        print(text)
        return
    if json_path is not None:
        Path(json_path).parent.mkdir(parents=True, exist_ok=True)
        Path(json_path).write_text(text + "\n")
    print(json.dumps(headline(summary), default=str))
    sys.stdout.flush()
