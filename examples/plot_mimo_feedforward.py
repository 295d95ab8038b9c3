"""
MIMO feedforward on a virtual steering mirror
=============================================

A fine steering mirror with three piezo actuators (V) and three displacement sensors (m): two
MIMO models with hysteresis in a feedback path were identified from the CubeSpec mirror's
multisine records (``examples/data/README.md``), one from realizations 1-3 and one from
realizations 4-6. The first computes the feedforward; the second plays the mirror it is applied
to — the feedforward never sees the model it is scored on.

The reference is a Lissajous figure in tip and tilt (90 Hz and 120 Hz, 0.1 mrad, piston held at
zero), mapped to the three sensors by the mirror geometry (sensors 20 mm from the centre, 120
degrees apart; :func:`~piezohyst.control.mirror_matrix`). Three feedforwards are compared:

* **static**: the inverse of the model's DC gain, what a quasi-static calibration gives;
* **linear**: :class:`~piezohyst.control.MimoFeedforward`'s least-squares inversion of the
  linearized dynamics over the periodic reference, within 1.5 kHz;
* **full**: the same, refined by iterating on the hysteretic model's own simulation
  (:meth:`~piezohyst.control.MimoFeedforward.iterate`), which inverts the amplitude-dependent
  part the linearization leaves out.
"""

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from piezohyst.control import MimoFeedforward, mirror_matrix
from piezohyst.control.mimo import frequency_response
from piezohyst.models.mimo import load_mimo_model

data = Path("data") if Path("data").is_dir() else Path(__file__).resolve().parent / "data"
model = load_mimo_model(data / "fsm_lfr_123.json")  # for the feedforward
mirror = load_mimo_model(data / "fsm_lfr_456.json")  # the virtual mirror
fs = model.fs

n = 3200  # one period: 0.5 s
t = np.arange(n) / fs
amp = 1e-4  # rad
ptt = np.column_stack([np.zeros(n), amp * np.sin(2 * np.pi * 90 * t), amp * np.sin(2 * np.pi * 120 * t + 0.3)])
M = mirror_matrix(0.02)  # (piston, tip, tilt) -> three sensors
r = ptt @ M.T  # the sensors' reference, m


def on_mirror(u):
    """The mirror's tip and tilt in the third period of the periodic command ``u``."""
    y = mirror.simulate(np.tile(u, (3, 1)), init="rest")[-n:]
    return np.linalg.solve(M, y.T).T[:, 1:]


ff = MimoFeedforward.from_model(model, bandwidth=1500.0)
g0 = frequency_response(ff.A, ff.B, ff.C, ff.D, [0.0], fs)[0].real
commands = {
    "static": np.linalg.solve(g0, r.T).T,
    "linear": ff.linear_command(r),
}
commands["full"], model_error = ff.iterate(
    lambda u: model.simulate(u, init="rest"), r, iterations=3, periods=3, gain=0.7
)
print(f"model error over the iterations (m RMS): {np.array2string(model_error, precision=3)}")

fig, axes = plt.subplots(1, 2, figsize=(10, 4), layout="constrained")
axes[0].plot(ptt[:, 1] * 1e3, ptt[:, 2] * 1e3, "k", lw=2, label="reference")
for name, u in commands.items():
    got = on_mirror(u)
    err = got - ptt[:, 1:]
    rms = np.sqrt(np.mean(err**2, axis=0)) / amp * 100
    print(
        f"{name:6s} tip error {rms[0]:5.2f} %, tilt error {rms[1]:5.2f} % of 0.1 mrad; |u| <= {np.abs(u).max():.2f} V"
    )
    axes[0].plot(got[:, 0] * 1e3, got[:, 1] * 1e3, lw=1, label=name)
    axes[1].plot(t * 1e3, np.hypot(err[:, 0], err[:, 1]) * 1e6, lw=1, label=name)
axes[0].set(xlabel="tip [mrad]", ylabel="tilt [mrad]", title="Lissajous 90/120 Hz on the virtual mirror")
axes[1].set(xlabel="time [ms]", ylabel="pointing error [urad]", title="error (held-out mirror model)", yscale="log")
axes[0].legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=4, fontsize=8)
plt.show()
