"""
Compensate hysteresis with the inverse model
============================================

"Measure" the built-in virtual stage (a simulated piezo flexure stage with CEMF hysteresis,
creep, a real amplifier and a quantized, noisy, delayed sensor), identify seed 2's MPI model
on that record, and track a 50 Hz sine open loop and behind the model's exact inverse.
"""

import matplotlib.pyplot as plt
import numpy as np

import piezohyst as ph
from piezohyst.plant import excitation, measure

stage = ph.virtual_stage()
fs = 1 / stage.sample_time
u, y = measure(stage, excitation(fs), np.random.default_rng(0))  # V in, m out
fit = ph.identify_mpi(u, y, operators=9)
print(fit)

t, ref = ph.sine(50, 8e-6, 0.2, fs, offset=9e-6)  # 8 um amplitude around 9 um
runs = {
    "open loop": ph.OpenLoop(),
    "inverse feedforward": ph.InverseFeedforward(fit.model, c1=1e-4),
}
fig, axes = plt.subplots(1, 2, figsize=(10, 3.6), layout="constrained")
for name, controller in runs.items():
    res = ph.track(controller, ref, stage=stage, rng=1, skip=0.1)
    m = res.metrics
    print(f"{name:20s} RMSE {m['rmse'] * 1e6:.3f} um, linearity error {m['linearity_error']:.2f} %")
    keep = res.time >= 0.1
    axes[0].plot(res.reference[keep] * 1e6, res.position[keep] * 1e6, lw=1, label=name)
    axes[1].plot(res.time[keep], res.error[keep] * 1e6, lw=1, label=name)
axes[0].set(xlabel="desired position [um]", ylabel="position [um]", title="output against desired")
axes[1].set(xlabel="time [s]", ylabel="error [um]", title="tracking error")
axes[0].legend()
