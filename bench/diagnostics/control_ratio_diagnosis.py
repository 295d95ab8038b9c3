"""What limits the 80 Hz compensated loop against the tuned PID + static feedforward (issue 19;
written when the ratio was 5-6x, it found the MPI inverse's 160/240 Hz shape error, now cut by
the operating-range identification): at one seed, rebuild the study's identified models (the
same draws as :func:`piezohyst.papers.control_study.compensation_study`), then

- grid both loops' (kp, ki) on the true stage (median normalized max error of 3 noise seeds):
  is either tuning stuck?
- run the tuned compensated loop and its feedforward alone without sensor noise and
  quantization: the floor, and the error's largest harmonics.

Run: ``.venv/bin/python bench/diagnostics/control_ratio_diagnosis.py [--seed 1] [--objective max_error]``
(prints; writes nothing).
"""

from __future__ import annotations

import argparse
import itertools
import warnings

import numpy as np

import piezohyst as ph
from piezohyst.control.controllers import PID, Compensated, FilteredPID, InverseFeedforward
from piezohyst.control.filters import LowPass
from piezohyst.control.frequency import DynamicInversion, measure_frf
from piezohyst.control.tuning import track
from piezohyst.papers.control_study import compensation_study, identify_operating_mpi
from piezohyst.papers.experiments import identify_stage_cemf, steady_sine
from piezohyst.plant.stage import Sensor


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--objective", default="max_error", choices=["rmse", "max_error"])
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    stage = ph.virtual_stage()
    fs = 1 / stage.sample_time
    out = compensation_study(stage, np.random.default_rng(args.seed), objective=args.objective)
    print(
        "study:",
        {
            a: (r["PID+FF"]["normalized_max_error"], r["compensated"]["normalized_max_error"], r["ratio"])
            for a, r in out["table4_80hz"].items()
        },
    )
    rng = np.random.default_rng(args.seed)  # the study's draws, in its order
    mech, _, _ = identify_stage_cemf(stage, rng, max_iterations=60)
    law = identify_operating_mpi(stage, rng)[0].model
    frf = measure_frf(
        stage,
        InverseFeedforward(law),
        method="stepped",
        points=12,
        band=(2.0, 300.0),
        amplitude=8e-6,
        offset=9e-6,
        rng=int(rng.integers(0, 2**31)),
    )
    dyn = DynamicInversion.fit(frf)
    g = mech.tem / mech.stiffness
    ref, k0 = steady_sine(80, 8e-6, 9e-6, fs, False)

    def med(c):
        try:
            return float(
                np.median(
                    [
                        track(c, ref, stage=stage, rng=s, skip=k0 / fs).metrics["normalized_max_error"]
                        for s in (11, 12, 13)
                    ]
                )
            )
        except ValueError:
            return float("inf")

    print("grid (linearized kp, ki): compensated, PID+FF (the same gains over the static gain)")
    for kp, ki in itertools.product([0.01, 0.05, 0.2, 0.5, 1.0], [300, 1000, 2000, 4000, 8000]):
        c = Compensated(FilteredPID(notches=(LowPass(2000.0),), kp=kp, ki=ki, **dyn.feedforward()), law)
        print(f"  {kp:5g} {ki:5g}  {med(c):.5f}  {med(PID(ff_gain=1 / g, kp=kp / g, ki=ki / g)):.5f}")
    gains = out["gains"]["compensated"]
    comp = Compensated(
        FilteredPID(notches=(LowPass(2000.0),), kp=gains["inner.kp"], ki=gains["inner.ki"], **dyn.feedforward()), law
    )
    clean = stage.with_(sensor=Sensor(0.0, 0.0, stage.sensor.delay))
    for name, c in (("compensated", comp), ("feedforward alone", Compensated(FilteredPID(**dyn.feedforward()), law))):
        res = track(c, ref, stage=clean, rng=1)
        e = (res.position - res.reference)[k0:]
        spec = np.fft.rfft(e) / e.size * 2
        f = np.fft.rfftfreq(e.size, 1 / fs)
        top = np.argsort(-np.abs(spec))[:5]
        print(
            f"{name} without sensor noise: normalized max error "
            f"{track(c, ref, stage=clean, rng=1, skip=k0 / fs).metrics['normalized_max_error']:.5f}; "
            "largest components (Hz, nm): " + ", ".join(f"{f[i]:.0f} {abs(spec[i]) * 1e9:.1f}" for i in top)
        )


if __name__ == "__main__":
    main()
