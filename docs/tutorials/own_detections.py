"""# Track your own detections from Python

You have detections — from a radar, a camera, an ADS-B receiver, a simulation — and want
tracks. The tracker takes one batch of detections at a time (one scan, or one antenna
sector) as positions in a local Cartesian frame with their covariance, and returns every
live track after that batch. No sensor model, no simulator and no network are needed.
"""

# %%
# ## Detections in a local frame, in 20 lines
#
# Two aircraft fly straight; a sensor sees each one with probability 0.9 every 4 s, with
# a position error σ = 50 m, among 30 false detections spread over 100 km × 100 km.
# `batch_from_positions(time, xy, sigma)` turns each scan into a `MeasurementBatch`
# (x east, y north, metres; time in seconds; R = σ² I; the sensor's P_D is the
# `p_detection` argument, 0.9 by default).
import numpy as np
from skyfuse.fusion.tracker import Tracker, TrackerConfig, batch_from_positions

rng = np.random.default_rng(1)
tracker = Tracker(TrackerConfig(tracker="lmits", depth=3))
rho = 30 / (100e3 * 100e3)  # clutter density: false detections per m² per scan
for k in range(40):
    t = 4.0 * k  # s
    truth = np.array([[-20e3 + 200.0 * t, 5e3], [10e3, -15e3 + 150.0 * t]])  # m
    seen = (truth + rng.normal(0.0, 50.0, truth.shape))[rng.random(2) < 0.9]  # P_D = 0.9
    false = rng.uniform(-50e3, 50e3, (30, 2))
    batch = batch_from_positions(t, np.vstack([seen, false]), 50.0, clutter_density=rho)
    out = tracker.step(batch)  # all live tracks after this scan
for i in np.flatnonzero(out.confirmed):
    x, vx, y, vy = out.states[i]
    print(f"track {out.ids[i]}: ({x:8.0f}, {y:8.0f}) m, ({vx:4.0f}, {vy:4.0f}) m/s")
print("truth:", truth.round())

# %%
# ## What comes out
#
# `tracker.step(batch)` returns a `TrackerOutput`: arrays over all live tracks, confirmed
# or not, predicted to the batch time:
#
# * `ids` — track ids, stable over the track's life;
# * `states` (n, 4) — x, vx, y, vy (m, m/s); `covariances` (n, 4, 4);
# * `existence` — the probability that the track is a real target (the existence
#   trackers' ψ); `confirmed` — ψ passed the confirmation threshold `tau_confirm`;
# * `events` — confirmations, terminations and merges of this step.
print(f"{len(out)} live tracks, {int(out.confirmed.sum())} confirmed")
print("tentative tracks' existence:", np.round(out.existence[~out.confirmed], 3))

# %%
# Run it again and collect the events. Events concern confirmed tracks: each aircraft is
# confirmed once; the tentative tracks started from false detections stay at low
# existence and end without an event when ψ falls below `tau_terminate`. `out.stats`
# counts what each step did (plots, tracks started, terminated, ...).
tracker = Tracker(TrackerConfig(tracker="lmits", depth=3))
rng = np.random.default_rng(1)
events = []
for k in range(40):
    t = 4.0 * k
    truth = np.array([[-20e3 + 200.0 * t, 5e3], [10e3, -15e3 + 150.0 * t]])
    seen = (truth + rng.normal(0.0, 50.0, truth.shape))[rng.random(2) < 0.9]
    false = rng.uniform(-50e3, 50e3, (30, 2))
    batch = batch_from_positions(t, np.vstack([seen, false]), 50.0, clutter_density=rho)
    events += tracker.step(batch).events
kinds = [e.kind for e in events]
print({kind: kinds.count(kind) for kind in sorted(set(kinds))})
print([(e.time_ns / 1e9, e.kind, e.track_id) for e in events if e.kind == "confirmed"])

# %%
# ## Detections in WGS-84
#
# Detections given as latitude and longitude go through a system frame: here the
# stereographic plane tangent at the middle of the area (`SystemFrame.ned(...)` gives a
# local tangent plane instead, for areas under about 30 km). `batch_from_wgs84` converts
# the positions and carries the horizontal σ (metres, along the local east and north)
# through the frame's local Jacobian; `frame.to_geodetic` turns the tracks back into
# latitude and longitude.
from skyfuse.fusion.frames import SystemFrame
from skyfuse.fusion.tracker import batch_from_wgs84

frame = SystemFrame.stereographic(lat0=41.3, lon0=2.1)
tracker = Tracker(TrackerConfig(tracker="lmits", depth=3))
rng = np.random.default_rng(2)
for k in range(30):
    t = 4.0 * k
    lat = np.array([41.0 + 0.0018 * t, 41.6])  # one flies north, one east, ≈ 200 m/s
    lon = np.array([2.0, 1.7 + 0.0024 * t])
    lat_err, lon_err = rng.normal(0.0, 50.0 / 111e3, (2, 2))  # ≈ 50 m
    lat_seen, lon_seen = lat + lat_err, lon + lon_err / np.cos(np.radians(lat))
    out = tracker.step(batch_from_wgs84(t, lat_seen, lon_seen, sigma=50.0, frame=frame))
x, y = out.states[out.confirmed][:, 0], out.states[out.confirmed][:, 2]
lat_t, lon_t, _ = frame.to_geodetic(x, y, np.zeros_like(x))
for i, la, lo in zip(out.ids[out.confirmed], lat_t, lon_t):
    print(f"track {i}: lat {la:.4f}°, lon {lo:.4f}°")
print("truth:   lat", lat.round(4), "lon", lon.round(4))

# %%
# ## Next
#
# * Which tracker and which parameters: [the existence trackers](../concepts/trackers.md)
#   and the [configuration reference](../reference/configuration.md#tracker).
# * Compare trackers on a scenario with truth: [the next tutorial](compare_trackers.md).
# * Detections from several sensors: give each batch its own `radar_id`, `p_detection`
#   and `clutter_density`, in time order; the tracker keeps per-sensor coverage.
