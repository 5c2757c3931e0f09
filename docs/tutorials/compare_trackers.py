"""# Compare trackers on a scenario

Runs several existence trackers over the same simulated plots and scores them with GOSPA
(Rahmathullah, García-Fernández and Svensson, FUSION 2017) against the simulation truth.
The scenario is the thesis's five-target crossing ([thesis] §7.4: five targets at 25 m/s
flying in to a common point, crossing at scan 20, a Cartesian sensor with σ = 5 m,
P_D = 0.8, one scan per second), here with 20 false plots per scan over its 1 km × 1 km
area; the same plots feed every tracker.

The full Monte Carlo version of this comparison, with the retention table and curves, is
`skyfuse eval thesis-mtt-5 --trackers its,lmits --depths 1,3 --runs 50` (see
[Evaluate a tracker](../how-to/evaluate.md)).
"""

# %%
# ## The plots: one simulated run
#
# `simulate_run` gives the scans of one Monte Carlo run: the plots `z` of every scan
# (true and false, unlabelled for the tracker), the true states of the targets, the
# sensor's σ, P_D and the clutter density at each plot.
import time

import numpy as np
from skyfuse.fusion.evaluation import Experiment, Variant, simulate_run
from skyfuse.fusion.metrics.gospa import gospa
from skyfuse.fusion.tracker import Tracker, batch_from_positions

experiment = Experiment(scenario="thesis-mtt-5", scenario_params={"clutter_density": 2e-5})
run = simulate_run(experiment, run=0)
print(f"{len(run.z)} scans, {sum(len(z) for z in run.z)} plots, σ = {run.sigma2**0.5:.0f} m")

# %%
# ## Each tracker over the same plots
#
# A tracker is chosen by `TrackerConfig(tracker=..., depth=...)`; `depth` is the Singer
# memory depth N of ITS/LM-ITS/JITS (N = 0 is the IPDA form). `experiment.tracker_config`
# gives the source's settings for this scenario (CV motion with q = 0.75 m²/s⁴,
# v_max = 50 m/s, estimated clutter, ...) with the chosen kind and depth: a `TrackerConfig`
# like any other. At every scan the confirmed tracks' positions are compared with the
# live targets' (GOSPA, cut-off c = 25 m, order p = 2).


def score(config) -> dict:
    tracker = Tracker(config)
    sigma, pd = run.sigma2**0.5, run.p_detection
    distances, confirmed_false, cpu = [], 0, 0.0
    for k, (t, z) in enumerate(zip(run.time_ns * 1e-9, run.z)):
        rho = run.clutter_density[k]  # the clutter density at each plot
        batch = batch_from_positions(t, z, sigma, p_detection=pd, clutter_density=rho)
        t0 = time.process_time()
        out = tracker.step(batch)
        cpu += time.process_time() - t0
        est = out.states[out.confirmed][:, [0, 2]]
        alive = run.truth_alive[k]
        truth = run.truth_state[k, alive][:, [0, 2]]
        g = gospa(truth, est, c=25.0)
        distances.append(g.distance)
        confirmed_false = max(confirmed_false, g.n_false)
    return {
        "GOSPA": np.mean(distances),
        "final": distances[-1],
        "false": confirmed_false,
        "cpu": cpu,
    }


variants = {
    "ipda": Variant("ipda", 0),
    "its N=3": Variant("its", 3),
    "lmits N=3": Variant("lmits", 3),
    "jits N=3": Variant("jits", 3),
    "gnn": Variant("gnn", 0),
}
print(f"{'tracker':10s} {'mean GOSPA':>11s} {'final':>7s} {'false (max)':>12s} {'CPU s':>6s}")
for name, variant in variants.items():
    r = score(experiment.tracker_config(variant))
    print(f"{name:10s} {r['GOSPA']:9.1f} m {r['final']:5.1f} m {r['false']:12d} {r['cpu']:6.2f}")

# %%
# One run says little: the trackers differ mostly in false tracks and in how they
# keep the targets apart at the crossing, which needs many runs to see. `skyfuse eval`
# runs the same comparison over hundreds of runs, with ψ_init calibrated per tracker
# for the source's false-track rate ([Reproduction](../reproduction.md)).
