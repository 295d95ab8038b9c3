"""Shared test vectors for the C library (``make test-c``): Python computes, through the
compiled core, the outputs of every model family (forward and exact inverse) and of every
controller kind (alone, behind an identified MPI inverse, with ILC) on recorded inputs;
``tests/c/replay_vectors.c`` replays them through ``libpiezohyst`` and must match to 1e-12
(bit-identical is expected: the same Rust code runs).

Controller inputs are real closed-loop runs on the virtual stage: the generator records the
reference, its derivatives and the sensor readings, checks that stepping the controller
alone on those readings (``_core.controller_steps``) reproduces the closed loop's commands
bit for bit, and writes them.

File format (whitespace-separated tokens; floats as C99 hex literals, ``float.hex()``)::

    piezohyst-vectors 1
    forward NAME  model FAMILY N_DIMS DIMS... N_PARAMS PARAMS...  samples N  (v y)*N
    inverse NAME  model ...                                       samples N  (y_desired v)*N
    controller NAME  kind KIND N_PARAMS PARAMS...
        inverse none | inverse U_MIN U_MAX model ...
        ilc none | ilc PERIOD GAIN FORGETTING LEAD DELAY
        y0 Y0  samples N  (x_ref v_ref a_ref y u)*N
    end

Usage: ``python tests/c/gen_vectors.py OUT.txt``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

# the repository root, for tests.models_zoo (not tests/ itself: its folders, such as
# tests/control/, would shadow packages of the same name, python-control's 'control')
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.models_zoo import drive, zoo

import piezohyst as ph
from piezohyst import _core
from piezohyst.export_c import CONTROLLER_KINDS, FAMILY_CODES

SAMPLES = 2000
STEPS = 3000


def hx(x) -> str:
    return float(x).hex()


def model_tokens(family, dims, row) -> list[str]:
    return ["model", str(FAMILY_CODES[family]), str(len(dims)), *map(str, dims), str(len(row)), *map(hx, row)]


def identified_mpi(stage):
    """A 9-operator MPI model (V -> m) identified from a simulated measurement of the stage."""
    fs = 1.0 / stage.sample_time
    t = np.arange(int(2.0 * fs)) / fs
    u = 75 - 75 * np.clip(1 - 0.5 * t, 0.2, 1.0) * np.cos(2 * np.pi * 5 * t)
    x = stage.simulate(u).position
    return ph.identify_mpi(u[:-1], x[1:], operators=9).model


def controllers(stage, mpi):
    p = stage.params
    return {
        "open_loop": ph.OpenLoop(),
        "open_loop_dynamic": ph.OpenLoop(c1=1e-4, c2=1e-9),
        "pid": ph.PID(kp=2e6, ki=2e9, kd=20.0),
        "smc": ph.SMC(p),
        "smc_super_twisting": ph.SMC(p, switching="super_twisting", k1=10.0, k2=1000.0),
        "smc_cemf": ph.SMC(p, cemf=True, alpha=200.0, model_terms="measured"),
        "smc_cemf_desired_terms": ph.SMC(p, cemf=True, model_terms="desired"),
        "absmc": ph.ABSMC.for_stage(p),
        "absmc_mpi_inverse": ph.Compensated(
            ph.ABSMC.linearized(2000.0, 0.7, c1=2e3, lam=2e3, ks=5e3, gamma_d=1e4), mpi
        ),
        "cemf_feedforward": ph.CemfFeedforward(p),
        "mpi_inverse_feedforward": ph.InverseFeedforward(mpi, c1=stage.sample_time),
        "pid_ilc": ph.ILC(ph.PID(kp=2e6, ki=2e9), period=1000, gain=2e5),
        "pid_mpi_inverse_ilc": ph.ILC(ph.Compensated(ph.PID(kp=0.3, ki=1500.0), mpi), period=1000, gain=0.3),
        "smc_cemf_ilc": ph.ILC(ph.SMC(p, cemf=True), period=1000, gain=1e5, forgetting=0.99),
    }


def controller_case(name, c, stage, ref, vel, acc, seed) -> list[str]:
    kind, params, inverse, ilc = c.core(stage)
    spec = (kind, params, inverse, ilc)
    res = ph.closed_loop(stage, c, ref, velocity=vel, acceleration=acc, rng=seed)
    y0 = float(res.position[0])
    st = _core.controller_initial_state(spec, y0)
    u = _core.controller_steps(spec, ref, vel, acc, res.measured, st)
    if not np.array_equal(u, res.command):
        raise AssertionError(
            f"{name}: the controller stepped alone differs from the closed loop (max {np.max(np.abs(u - res.command))})"
        )
    toks = ["controller", name, "kind", str(CONTROLLER_KINDS[kind]), str(len(params)), *map(hx, params)]
    if inverse is None:
        toks += ["inverse", "none"]
    else:
        family, dims, row, lo, hi = inverse
        toks += ["inverse", hx(lo), hx(hi), *model_tokens(family, dims, row)]
    toks += ["ilc", "none"] if ilc is None else ["ilc", str(ilc[0]), hx(ilc[1]), hx(ilc[2]), str(ilc[3]), str(ilc[4])]
    toks += ["y0", hx(y0), "samples", str(len(u))]
    lines = [" ".join(toks)]
    lines += [" ".join(map(hx, row)) for row in zip(ref, vel, acc, res.measured, u, strict=False)]
    return lines


def generate() -> tuple[list[str], dict]:
    out = ["piezohyst-vectors 1"]
    counts = {"forward": 0, "inverse": 0, "controller": 0, "skipped_inverse": []}
    v = drive(SAMPLES)
    models = zoo()
    stage = ph.virtual_stage()
    mpi = identified_mpi(stage)
    models["mpi_identified"] = mpi
    for name, m in models.items():
        vin = v if name != "mpi_identified" else 75 + 70 * (v - 0.5) / 0.5
        y = m.simulate(vin)
        head = model_tokens(m.family, m.dims, m.to_row())
        out.append(" ".join(["forward", name, *head, "samples", str(len(y))]))
        out += [f"{hx(a)} {hx(b)}" for a, b in zip(vin, y, strict=False)]
        counts["forward"] += 1
        # the inverse of the model's own outputs, and of a perturbed copy (other guesses)
        desired = y + 1e-3 * (np.max(y) - np.min(y)) * np.sin(np.arange(y.size) * 0.05)
        try:
            vinv = m.inverse().simulate(desired)
        except ValueError:
            counts["skipped_inverse"].append(name)
            continue
        out.append(" ".join(["inverse", name, *head, "samples", str(len(desired))]))
        out += [f"{hx(a)} {hx(b)}" for a, b in zip(desired, vinv, strict=False)]
        counts["inverse"] += 1
    ts = stage.sample_time
    _, ref = ph.sine(10, 5e-6, STEPS * ts, 1 / ts, offset=8e-6)
    vel = np.gradient(ref, ts)
    acc = np.gradient(vel, ts)
    for seed, (name, c) in enumerate(controllers(stage, mpi).items()):
        out += controller_case(name, c, stage, ref, vel, acc, seed)
        counts["controller"] += 1
    out.append("end")
    return out, counts


def main(argv) -> int:
    if len(argv) != 2:
        print("usage: gen_vectors.py OUT.txt", file=sys.stderr)
        return 2
    lines, counts = generate()
    path = Path(argv[1])
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text("\n".join(lines) + "\n")
    os.replace(tmp, path)
    skipped = counts["skipped_inverse"]
    print(
        f"gen_vectors: {counts['forward']} forward, {counts['inverse']} inverse, {counts['controller']} controller "
        f"cases -> {path}" + (f" (no inverse for {', '.join(skipped)}: outputs not reachable)" if skipped else "")
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
