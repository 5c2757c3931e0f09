"""Monte Carlo evaluation of the trackers on the planar thesis scenarios ([thesis] ch. 7).

Pure computation (no files, no processes):

* ``experiment``: :class:`Experiment` (scenario, tracker variants, runs, seed, source
  settings) and :class:`Variant` (tracker kind, Singer depth);
* ``runner``: :class:`VariantRunner`, the per-run loop (simulate, track, label, histories,
  false tracks carried across runs) and :class:`RunBlock`;
* ``summary``: retention row and per-scan curves (CTT, false tracks, RMSE, GOSPA);
* ``calibration``: search of ψ_init for the source's number of confirmed false tracks.

``services/cmd_eval.py`` adds worker processes, the resumable cache, progress and files.
"""

from .calibration import Calibration, calibrate_psi_init
from .experiment import PLANAR_SCENARIOS, Experiment, Variant, run_seed
from .runner import RunBlock, RunInput, VariantRunner, simulate_run
from .summary import summarise

__all__ = [
    "PLANAR_SCENARIOS",
    "Calibration",
    "Experiment",
    "RunBlock",
    "RunInput",
    "Variant",
    "VariantRunner",
    "calibrate_psi_init",
    "run_seed",
    "simulate_run",
    "summarise",
]
