"""ITS component update ([thesis] (5.12)-(5.15), (4.70)-(4.71); multi-target β: §6.2.1).

Every predicted component c spawns a "no plot" child (ξ^{c,0} = β_0 ξ^c, x̂ and P
unchanged, 5.12) and one child per plot i it gated (ξ^{c,i} = β_i ξ^c p^c_i / p^τ_i with the
Kalman update and Joseph covariance, 5.14). With IPDA/ITS β this is (5.15); with JIPDA or
LM-IPDA β it is the multi-target update. The child's plot history is the new plot's id
(0 for none) followed by the first N−1 entries of the parent's history ([thesis] §5.3).

The update of a batch is one compiled call (:func:`.components_kernel.its_children`, with
the merge and pruning that follow it); :func:`shift_history` serves the out-of-sequence
update and the IMM density.
"""

from __future__ import annotations

import numpy as np


def shift_history(hist: np.ndarray, new_ids: np.ndarray) -> np.ndarray:
    """h' = (new id, h[0], …, h[N−2]); an (C, 0) history stays empty (N = 0)."""
    if hist.shape[1] == 0:
        return hist
    return np.column_stack([new_ids, hist[:, :-1]])
