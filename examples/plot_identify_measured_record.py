"""
Identify a model from a measured record
=======================================

A measured piezo micromanipulator (``examples/data/yan9a_model_1hz.dat``: 200 Hz, input
voltage in column 0, a capacitive sensor in raw units in column 4) — identify a Preisach
model and seed 2's modified Prandtl–Ishlinskii (MPI) model on one 1 Hz cycle, and validate
both on the next four cycles, the model state carried from training into validation.
"""

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import piezohyst as ph

data = Path("data") / "yan9a_model_1hz.dat"  # the gallery runs each example from examples/
rec = ph.load_record(data, input=0, output=4, fs=200.0)
train, val = rec.trim(3152, 3352), rec.trim(3352, 4152)
print(f"{rec.n} samples at {rec.fs:g} Hz; train {train.n}, validation {val.n}")

results = {}
for kind, options in {"preisach": {"levels": 10}, "mpi": {}}.items():
    res = ph.identify(train.input, train.output, kind, fs=rec.fs, validate=(val.input, val.output), **options)
    results[kind] = res
    m = res.metrics
    print(
        f"{kind:9s} train RMSE {m['train']['rmse_percent']:.3f} % of range, "
        f"validation {m['validation']['rmse_percent']:.3f} %"
    )

# %%
# The validation range against the models' predictions, each model run from the start of
# the training range so that its state is carried into validation (as the metrics above):

fig, ax = plt.subplots(figsize=(8, 3.5), layout="constrained")
t = np.arange(val.n) / rec.fs
ax.plot(t, val.output, "k", lw=2.5, label="measured")
for kind, res in results.items():
    y = res.simulate(np.concatenate([train.input, val.input]))[train.n :]
    ax.plot(t, y, lw=1, label=kind)
ax.set(xlabel="time in the validation range [s]", ylabel="sensor (raw units)")
ax.legend()
