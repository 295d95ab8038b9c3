"""
An XY stage with 5 % cross-coupling: decentralized PIDs, decoupling and sequential tuning
==========================================================================================

Two piezo axes (each the virtual stage: its amplifier, CEMF hysteresis, creep and a 1 nm
sensor) whose outputs are mixed by a 5 % coupling matrix, the typical XY flexure stage.
One PID with static feedforward per axis, the loop in the Rust core
(:func:`~piezohyst.control.closed_loop_multi`). We measure the crosstalk (y's error while only
x moves) with and without the static decoupler ``G^-1 diag(G)``, then tune both PIDs by
sequential loop closing (:func:`piezohyst.tune` on a
:class:`~piezohyst.plant.MultiAxisStage`) and track a raster scan.
"""

import matplotlib.pyplot as plt
import numpy as np

import piezohyst as ph
from piezohyst.control import closed_loop_multi
from piezohyst.plant import MultiAxisStage, Sensor

axis = ph.virtual_stage().with_(sensor=Sensor(quantization=1e-9, noise_std=1e-9, delay=1))
xy = MultiAxisStage.from_axes([axis, axis], coupling=0.05)
print(xy, "\nDC gain (um/V):\n", np.round(xy.dc_gain() * 1e6, 4))

# %%
# Crosstalk: x scans a 10 Hz sine of 10 µm peak to peak, y holds 6 µm.

t = np.arange(0, 0.4, xy.sample_time)
x_only = np.column_stack([8e-6 + 5e-6 * np.sin(2 * np.pi * 10 * t), np.full(t.size, 6e-6)])
pid = ph.PID(kp=2e6, ki=2e9)
fig, ax = plt.subplots(figsize=(8, 3.2), layout="constrained")
for decouple in (False, True):
    res = closed_loop_multi(xy, [pid, pid], x_only, decouple=decouple, rng=1).with_skip(0.1)
    label = "decoupled" if decouple else "decentralized only"
    print(f"{label:19s} x RMSE {res.rmse[0] * 1e9:6.1f} nm, y crosstalk RMSE {res.rmse[1] * 1e9:5.1f} nm")
    ax.plot(res.time, res.error[:, 1] * 1e9, lw=0.8, label=label)
ax.set(xlabel="time [s]", ylabel="y error while x moves [nm]")
ax.legend()

# %%
# Tuning both loops, each with the other closed (the same budget per axis as a single-axis
# :func:`piezohyst.tune`), behind the decoupler, on a raster: x a 20 Hz triangle, y a slow
# ramp across the field.

_, tri = ph.triangle(20, 4e-6, 0.5, 1 / xy.sample_time, offset=8e-6)
raster = np.column_stack([tri, np.linspace(4e-6, 10e-6, tri.size)])
box = {"kp": (1e5, 1e7), "ki": (1e8, 1e11)}
for plant, label in [(xy, "decentralized only"), (xy.with_decoupling(), "decoupled")]:
    tuned = ph.tune(
        [ph.PID(kp=1e6, ki=1e9)] * 2, box, raster, stage=plant, max_iterations=10, population_size=12, rng=0
    )
    run = closed_loop_multi(plant, list(tuned.controller), raster, rng=1).with_skip(0.1)
    cross = closed_loop_multi(plant, list(tuned.controller), x_only, rng=1).with_skip(0.1)
    print(
        f"{label:19s} tuned ({tuned.evaluations} closed loops, {tuned.wall_time:.2f} s): raster RMSE x/y "
        f"{run.rmse[0] * 1e9:.1f}/{run.rmse[1] * 1e9:.1f} nm, crosstalk {cross.rmse[1] * 1e9:.1f} nm"
    )
fig = run.plot()
