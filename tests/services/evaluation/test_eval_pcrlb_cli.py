"""``skyfuse eval thesis-mtt-5`` writes the PCRLB floor beside the RMSE (JSON and PNG).

Reference: the thesis-mtt targets fly straight lines (truth q = 0) from scan 1, so the
floor over all targets is the least-squares line fit with the information reduction
factor P_D = 0.8: 2σ²(2k − 1)/(k(k + 1))/P_D per axis after k scans, σ² = 25 m²; the
P_D = 1 floor is P_D times the P_D floor (information scales by P_D)."""

from __future__ import annotations

import json

import numpy as np
from skyfuse.services.cli.main import main


def test_eval_writes_the_pcrlb_beside_the_rmse(tmp_path):
    out = tmp_path / "o"
    argv = ["eval", "thesis-mtt-5", "--trackers", "lmits", "--depths", "1", "--runs", "2",
            "--seed", "1", "--out", str(out), "--no-progress"]  # fmt: skip
    assert main(argv) == 0
    c = json.loads((out / "thesis-mtt-5.json").read_text())["curves"]["lmits:1"]
    k = np.arange(1, 41)
    closed = 2 * 2 * 25.0 * (2 * k - 1) / (k * (k + 1)) / 0.8
    got = np.array(c["pcrlb_targets_m"], float)
    assert np.allclose(got**2, closed, rtol=2e-3)
    assert c["pcrlb_model"]["q"] == 0.0 and c["pcrlb_model"]["p_detection"] == 0.8
    rows = np.array(c["rmse_rows"]) > 0
    assert rows.sum() > 10
    assert all(c["pcrlb_m"][i] is not None for i in np.flatnonzero(rows))
    assert all(c["pcrlb_m"][i] is None for i in np.flatnonzero(~rows))
    # P_D = 1 floor: with q = 0 and the diffuse prior the information scales by P_D
    full = np.array([np.nan if v is None else v for v in c["pcrlb_all_detected_m"]])
    floor = np.array([np.nan if v is None else v for v in c["pcrlb_m"]])
    assert np.allclose((full / floor)[rows] ** 2, 0.8, rtol=2e-3)
    assert (out / "thesis-mtt-5-rmse.png").stat().st_size > 5000
