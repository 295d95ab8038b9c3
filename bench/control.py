"""Control acceptance on the virtual stage (issue 5): seed 1 Table 3 and seed 2 Tables 3-4
patterns, with every model identified from simulated measurements (commanded voltage and
the quantized, noisy sensor reading), plus gain-tuning wall time (one controller step in
ns: ``cargo run --release -p piezohyst-core --example controller_step``). Writes ``bench/results/control.json``.

Run: ``.venv/bin/python bench/control.py [--quick]``.
"""
from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

import piezohyst as ph
from piezohyst.control import ABSMC, SMC, Compensated, InverseFeedforward, OpenLoop, VelocityObserver

OUT = Path(__file__).with_name("results") / "control.json"


def measure(stage, u, rng):
    """What a lab records: the command and the sensor reading (noise, quantization; the
    reading at k+1 shows the position the command at k produced)."""
    x = stage.simulate(u).position
    q = stage.sensor.quantization
    y = np.round((x + stage.sensor.noise_std * rng.standard_normal(x.size)) / q) * q
    return u[:-1], y[1:]


def excitation(fs, seconds=2.0, freq=5.0):
    """Full-range sine with a decaying envelope from 0 V: major loop, then nested minor loops."""
    t = np.arange(int(seconds * fs)) / fs
    env = np.clip(1 - 0.8 * (t - 0.4) / (seconds - 0.4), 0.2, 1.0)
    return 75 - 75 * env * np.cos(2 * np.pi * freq * t)


def steady_sine(f, amp, off, fs, variable, warm=1.0):
    """``warm`` s of constant-amplitude sine, then two periods (constant, or decaying
    envelope for 'variable'); returns the reference and the first evaluated sample."""
    n_warm = int(round(fs * (warm + 1 / (4 * f))))
    _, w = ph.sine(f, amp, n_warm / fs, fs, offset=off)
    if variable:
        _, tail = ph.variable_amplitude_sine(f, amp, 2 / f, fs, offset=off)
    else:
        _, tail = ph.sine(f, amp, 2 / f, fs, offset=off, phase=0.0)
    return np.r_[w[:n_warm], tail], n_warm


def seed1(stage, fs, rng, quick):
    u, y = measure(stage, excitation(fs, 0.6, 5.0), rng)
    t0 = time.perf_counter()
    ident = ph.identify_cemf(u, y, fs, optimizer="de", rng=1, max_iterations=60 if quick else 100)
    t_ident = time.perf_counter() - t0
    m = ident.model
    # the mass is invisible at 5 Hz: take it from the measured first resonance (FRF test)
    f_res = stage._resonance()
    k = m.stiffness / m.tem
    mass = k / (2 * np.pi * f_res) ** 2
    model = dataclasses.replace(m, mass=mass * m.tem, damping=2 * 0.03 * np.sqrt(k * mass) * m.tem)
    refs = {name: fn(f, 5e-6, 1.0, fs, offset=7e-6)[1]
            for name, (fn, f) in {"triangle 5 Hz": (ph.triangle, 5), "triangle 10 Hz": (ph.triangle, 10),
                                  "sine 5 Hz": (ph.sine, 5)}.items()}
    template = SMC(model, observer=VelocityObserver(300.0))
    plant = ph.stage_from_model(stage, model)
    box = {"kp": (1e5, 3e7), "kv": (3e2, 1e4), "ks": (2.0, 60.0), "phi": (1e-3, 0.1)}
    tunings = {case: ph.tune(dataclasses.replace(template, cemf=case == "SMC+CEMF"), box, [refs["triangle 5 Hz"][:5000]],
                             stage=plant, method="css", rng=1, max_iterations=10 if quick else 30, population_size=16,
                             skip=0.1)
               for case in ("SMC", "SMC+CEMF")}
    # the seed's operating point: gains at which Case 1 tracks at the seed's level (~0.1 um)
    gain_sets = {"tuned for SMC": tunings["SMC"].controller, "tuned for SMC+CEMF": tunings["SMC+CEMF"].controller,
                 "seed-level (kp 1e6, kv 2e3, ks 20, phi 0.01)": dataclasses.replace(template, kp=1e6, kv=2e3, ks=20.0, phi=0.01)}
    rows = {}
    for set_name, gains_c in gain_sets.items():
        for name, ref in refs.items():
            row = {}
            for label, c in (("open loop", OpenLoop()), ("SMC", dataclasses.replace(gains_c, cemf=False)),
                             ("SMC+CEMF", dataclasses.replace(gains_c, cemf=True))):
                res = ph.track(c, ref, stage=stage, rng=1, skip=0.2)
                row[label] = res.metrics["rmse"] * 1e6
            row["CEMF cut %"] = 100 * (1 - row["SMC+CEMF"] / row["SMC"])
            rows.setdefault(set_name, {})[name] = row
    gains = {k: {n: getattr(c, n) for n in box} for k, c in gain_sets.items()}
    tuning = tunings["SMC"]
    return {"identification_s": t_ident, "identified": {"M": model.mass / model.tem, "B": model.damping / model.tem,
                                                          "K": k, "tem": m.tem, "alpha": m.hyst_alpha,
                                                          "beta": m.hyst_beta, "gamma": m.hyst_gamma,
                                                          "fit_rmse_percent": ident.train["rmse_percent"],
                                                          "resonance_hz": f_res},
            "gains": gains, "tuning_wall_s": {k: t.wall_time for k, t in tunings.items()},
            "tuning_nfev": tuning.nfev, "tuning_rmse_on_model_um": {k: t.rmse * 1e6 for k, t in tunings.items()},
            "amplitude_um": 5.0, "offset_um": 7.0, "rmse_um": rows,
            "seed_rmse_um": {"triangle 5 Hz": {"SMC": 0.1118, "SMC+CEMF": 0.0715},
                             "sine 5 Hz": {"SMC": 0.1007, "SMC+CEMF": 0.0539}}}


def lag_of(stage, model, fs, rng):
    """The loop's lag (s), from the feedforward's residual on a 100 Hz sine: regress the
    deviation from the best line on the reference velocity."""
    ref, k0 = steady_sine(100, 8e-6, 9e-6, fs, False, warm=0.3)
    res = ph.closed_loop(stage, InverseFeedforward(model), ref, rng=rng)
    x, y = ref[k0:], res.position[k0:]
    a, b = np.polyfit(x, y, 1)
    v = np.gradient(ref, 1 / fs)[k0:]
    coef = np.linalg.lstsq(np.c_[v, np.ones_like(v)], y - (a * x + b), rcond=None)[0]
    return float(-coef[0])


def seed2(stage, fs, rng, quick):
    u, y = measure(stage, excitation(fs), rng)
    t0 = time.perf_counter()
    fit = ph.identify_mpi(u, y, operators=9, creep=ph.Creep(1 / fs, [0.01, 0.1, 1.0], [0, 0, 0]))
    t_ident = time.perf_counter() - t0
    model = fit.model
    lag = lag_of(stage, model, fs, 1)
    ff = InverseFeedforward(model, c1=lag)
    amp, off = 8e-6, 9e-6
    table3 = {}
    for f in (10, 20, 50, 100):
        for variable in (False, True):
            ref, k0 = steady_sine(f, amp, off, fs, variable)
            none = ph.track(OpenLoop(), ref, stage=stage, rng=1, skip=k0 / fs).metrics["linearity_error"]
            comp = ph.track(ff, ref, stage=stage, rng=1, skip=k0 / fs).metrics["linearity_error"]
            table3[f"{f} Hz {'variable' if variable else 'constant'}"] = {"none": none, "feedforward": comp}
    # the linearized loop seen by the feedback: unit gain with the measured lag, as a
    # second-order model 2 zeta / omega_n = lag, zeta = 0.7
    fn = 1.4 / lag / (2 * np.pi)
    absmc = Compensated(ABSMC.linearized(fn, 0.7, c1=2e3, lam=2e3, ks=5e3, gamma_d=1e4,
                                         observer=VelocityObserver(1000.0)), model)
    table4 = {}
    for variable in (False, True):
        ref, k0 = steady_sine(80, amp, off, fs, variable)
        row = {}
        for label, c in (("none", OpenLoop()), ("feedforward", ff), ("feedforward+ABSMC", absmc)):
            mt = ph.track(c, ref, stage=stage, rng=1, skip=k0 / fs).metrics
            row[label] = {"normalized_max_error": mt["normalized_max_error"],
                          "normalized_rms_error": mt["normalized_rms_error"]}
        table4["variable" if variable else "constant"] = row
    return {"identification_s": t_ident, "mpi_fit": repr(fit),
            "lag_s": lag, "linearized_natural_frequency_hz": fn, "amplitude_um": amp * 1e6, "offset_um": off * 1e6,
            "table3_linearity_percent": table3, "table4_80hz": table4,
            "seed_table3": {"10 Hz constant": [5.53, 0.17], "20 Hz constant": [7.44, 0.38], "50 Hz constant": [8.56, 0.53],
                            "100 Hz constant": [13.05, 0.67], "10 Hz variable": [7.37, 0.36], "100 Hz variable": [14.88, 0.74]},
            "seed_table4": {"constant": [0.0784, 0.0099, 0.0054], "variable": [0.1199, 0.0118, 0.0055]}}


def main():
    quick = "--quick" in sys.argv
    stage = ph.virtual_stage()
    fs = 1 / stage.sample_time
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    s1 = seed1(stage, fs, rng, quick)
    s2 = seed2(stage, fs, rng, quick)
    result = {"seed1_table3": s1, "seed2": s2,
              "wall_s": time.perf_counter() - t0, "quick": quick}
    OUT.parent.mkdir(exist_ok=True)
    OUT.write_text(json.dumps(result, indent=1, default=float))
    print(json.dumps(result, indent=1, default=float))


if __name__ == "__main__":
    main()
