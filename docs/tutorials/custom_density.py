"""# A custom track density

The existence trackers keep each track's kinematic state in a **track density** — a
Gaussian mixture with Singer memory, an IMM mixture, a particle cloud — behind one small
interface, `skyfuse.fusion.tracker.density.base.TrackDensity` ([the tracker's
parts](../concepts/tracker-parts.md)). The tracker never looks inside: per batch it asks
the density to predict the tracks the batch could have seen, to gate the plots and give
their likelihoods, and, once association has weighed the hypotheses (β₀ for "no plot",
β_i for plot i), to update. Existence, association, initiation and track management stay
the tracker's; the per-track state lives in the tracker's track store, where the density
declares its columns.

This tutorial writes the simplest density — one Gaussian per track with the
constant-velocity model, the density of IPDA ([thesis] (2.37)–(2.38)) — registers it
under a name, and checks it against the built-in one on the same plots.
"""

# %%
# ## The density
#
# Its per-track state is two columns of the track store, `x` (n, 4) in the layout x, vx,
# y, vy and `P` (n, 4, 4), declared in `attach` (`estimate_group`: a new track's columns
# are its initial Gaussian). `late_plots = "current"`: a plot older than a track's state
# is applied at the track's current time (a density that can retrodict says
# `"retrodict"` and implements the out-of-sequence update as well).
import numpy as np
from skyfuse.fusion.association.gating import gate, gate_probability
from skyfuse.fusion.models.cv import ConstantVelocity
from skyfuse.fusion.tracker.density.base import GatedTable, Prediction, estimate_group


class OneGaussian:
    """IPDA's density: one Gaussian per track, CV motion, PDA update."""

    late_plots = "current"

    def __init__(self, q: float) -> None:
        self.model = ConstantVelocity(q=q, ndim=2)
        self.H = self.model.H()
        self.dim = self.model.dim
        self.stats: dict[str, int] = {}

    def attach(self, tracks) -> None:  # declare the columns x, P in the track store
        tracks.declare(estimate_group(self.dim))
        self.tracks = tracks

    def predict(self, rows, dt):
        x, P = self.model.predict(self.tracks.x[rows], self.tracks.P[rows], dt)
        pred = Prediction(rows, x @ self.H.T, self.H @ P @ self.H.T)
        pred.x, pred.P = x, P  # kept for the update
        return pred

    def likelihoods(self, pred, z, R, g):
        pairs = gate(pred.z_mean, pred.S0, z, R, g)  # d² < g, with S = H P Hᵀ + R
        p = np.exp(pairs.log_pdf) / gate_probability(g, 2)  # N(ν; 0, S) / P_G   (4.17)
        table = GatedTable(pairs.state, pairs.plot, p)
        table.pairs = pairs
        return table

    def update(self, pred, table, beta0, beta):
        pairs = table.pairs  # hypotheses: no plot (β₀), or gated plot i (β_i)
        K = pred.P[pairs.state] @ self.H.T @ np.linalg.inv(pairs.S)  # Kalman gain per pair
        xi = pred.x[pairs.state] + np.einsum("pij,pj->pi", K, pairs.nu)
        Pi = pred.P[pairs.state] - K @ pairs.S @ np.swapaxes(K, 1, 2)
        # the moment-matched mixture (2.37): x̂ = Σ β_i x̂_i, P = Σ β_i (P_i + x̂_i x̂_iᵀ) − x̂ x̂ᵀ
        x = beta0[:, None] * pred.x
        np.add.at(x, pairs.state, beta[:, None] * xi)
        P = beta0[:, None, None] * (pred.P + pred.x[:, :, None] * pred.x[:, None, :])
        np.add.at(P, pairs.state, beta[:, None, None] * (Pi + xi[:, :, None] * xi[:, None, :]))
        P -= x[:, :, None] * x[:, None, :]
        self.tracks.x[pred.rows] = x
        self.tracks.P[pred.rows] = 0.5 * (P + np.swapaxes(P, 1, 2))

    def estimate(self, rows):
        return self.tracks.x[rows].copy(), self.tracks.P[rows].copy()

    def estimates_view(self):  # all tracks, read only
        return self.tracks.x, self.tracks.P

    def component_counts(self):
        return np.ones(len(self.tracks), np.int64)

    def to_snapshot(self) -> dict:  # nothing outside the track store's columns
        return {}

    def from_snapshot(self, snap) -> None:
        pass


# %%
# ## Register it and give it to a tracker
#
# One registration (`skyfuse.fusion.tracker.registry`) makes it a motion like the
# built-in ones: `TrackerConfig(motion="one-gaussian")` accepts the name, and the
# tracker's out-of-sequence pass, snapshots and kernel warm-up work through the
# interface with no other change.
from skyfuse.fusion.tracker import Tracker, TrackerConfig, batch_from_positions
from skyfuse.fusion.tracker.registry import register_motion

register_motion("one-gaussian", lambda cfg: OneGaussian(q=cfg.q), "one Gaussian, CV (tutorial)")
mine = Tracker(TrackerConfig(tracker="ipda", motion="one-gaussian"))
builtin = Tracker(TrackerConfig(tracker="ipda", motion="cv"))

# %%
# ## Same plots, same tracks
#
# Two aircraft among clutter, as in the first tutorial, fed to both trackers.
rng = np.random.default_rng(1)
for k in range(40):
    t = 4.0 * k
    truth = np.array([[-20e3 + 200.0 * t, 5e3], [10e3, -15e3 + 150.0 * t]])
    seen = (truth + rng.normal(0.0, 50.0, truth.shape))[rng.random(2) < 0.9]
    plots = np.vstack([seen, rng.uniform(-50e3, 50e3, (30, 2))])
    batch = batch_from_positions(t, plots, 50.0, p_detection=0.9, clutter_density=30 / 1e10)
    out_mine, out_builtin = mine.step(batch), builtin.step(batch)

print("confirmed ids, mine:    ", out_mine.ids[out_mine.confirmed])
print("confirmed ids, built-in:", out_builtin.ids[out_builtin.confirmed])
same = np.array_equal(out_mine.ids, out_builtin.ids)
diff = np.abs(out_mine.states - out_builtin.states).max() if same else np.inf
print(f"same tracks: {same}; largest state difference {diff:.2e} (m, m/s)")
