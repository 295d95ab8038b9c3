"""The demo: forward and exact inverse of the seed-2 reference MPI model.

Until the full end-to-end demo (identification, control, report) lands, this shows the core
at work: the MPI model of seed 2, Table 1, driven by a variable-amplitude sine (nested minor
loops), then inverted sample by sample so that a straight-line desired output is tracked.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .pi import mpi_seed2
from .references import variable_amplitude_sine

__all__ = ["run_demo"]


def run_demo(out_dir="piezohyst-report", *, force=False, fs=10_000.0, freq=10.0, print_fn=print) -> dict:
    """Run the demo, write ``mpi_loops.png`` into ``out_dir``, return the numbers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    figure = out_dir / "mpi_loops.png"
    if figure.exists() and not force:
        raise FileExistsError(f"{figure} exists; pass --force to overwrite it")
    out_dir.mkdir(parents=True, exist_ok=True)

    model = mpi_seed2()
    t, v = variable_amplitude_sine(freq, 0.45, 0.5, fs, offset=0.5)
    t0 = time.perf_counter()
    y = model.simulate(v)
    t_forward = time.perf_counter() - t0

    # Compensation: ask for an output that is a straight line of the input command.
    gain = (y.max() - y.min()) / (v.max() - v.min())
    y_desired = gain * (v - v.min()) + y.min()
    t0 = time.perf_counter()
    v_comp = model.inverse().simulate(y_desired)
    t_inverse = time.perf_counter() - t0
    y_comp = model.simulate(v_comp)
    residual = float(np.max(np.abs(y_comp - y_desired)))
    span = float(y.max() - y.min())
    fit = np.polyfit(y_desired, y, 1)
    lin_before = 100 * float(np.max(np.abs(y - np.polyval(fit, y_desired)))) / span
    fit = np.polyfit(y_desired, y_comp, 1)
    lin_after = 100 * float(np.max(np.abs(y_comp - np.polyval(fit, y_desired)))) / span

    fig, ax = plt.subplots(1, 3, figsize=(14, 4.2))
    ax[0].plot(v, y, lw=0.8)
    ax[0].set(title="Seed-2 MPI: hysteresis loops", xlabel="input v (normalized)", ylabel="output y (normalized)")
    ax[1].plot(y_desired, y, lw=0.8, label="uncompensated")
    ax[1].plot(y_desired, y_comp, lw=1.2, label="with exact inverse")
    ax[1].set(title="Output vs desired", xlabel="desired y_d", ylabel="output y")
    ax[1].legend()
    ax[2].plot(t, y_comp - y_desired, lw=0.8)
    ax[2].set(title=f"Inverse residual (max {residual:.1e})", xlabel="time (s)", ylabel="y - y_d")
    fig.tight_layout()
    fig.savefig(figure, dpi=110)
    plt.close(fig)

    numbers = {
        "samples": int(v.size),
        "forward_seconds": t_forward,
        "inverse_seconds": t_inverse,
        "inverse_max_residual": residual,
        "linearity_error_percent_uncompensated": lin_before,
        "linearity_error_percent_compensated": lin_after,
        "figure": str(figure),
    }
    print_fn(f"seed-2 MPI (Table 1), variable-amplitude {freq:g} Hz sine, {v.size} samples at {fs:g} Hz")
    print_fn(f"  forward simulation      {t_forward * 1e3:8.2f} ms")
    print_fn(f"  exact inverse           {t_inverse * 1e3:8.2f} ms")
    print_fn(f"  inverse max residual    {residual:.3e}  (max |y(inverse(y_d)) - y_d|)")
    print_fn(f"  linearity error         {lin_before:.2f} % uncompensated -> {lin_after:.2e} % with the inverse")
    print_fn(f"  figure                  {figure}")
    return numbers
