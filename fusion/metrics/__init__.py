"""Evaluation measures over NumPy arrays ([thesis] §7.1-7.2).

One measure per module, no tracker objects: inputs are arrays of truth and track ids,
positions, covariances and labels per scan.

* ``point_pattern``: input checks, cut-off distance matrix, optimal assignment (shared).
* ``gospa``: GOSPA per scan with its decomposition, and over time with a track-switch term.
* ``ospa``: OSPA (Schuhmacher, Vo & Vo 2008).
* ``labelling``: truth labelling of tracks ([thesis] §7.1, eq. 7.1).
* ``mtt_measures``: CTT rate, cumulative confirmed false tracks, RMSE of confirmed true tracks.
* ``retention``: the retention table ([thesis] §7.2.1).
* ``label_metrics``: measures for recordings whose truth is only plot labels (Mode-S).
* ``turn_phase``: truth samples in a turn or in straight flight (turn rate from velocities),
  RMSE per phase.
* ``reference_association``: which reference aircraft (ADS-B / multilateration, with an
  address) each track update belongs to: nearest within a gate, majority along the track.
* ``reference_scores``: tracks against that reference (ED-116/ED-117, ESASSP style):
  probability of update, position error, continuity, duplicates, false tracks, identity.
"""
