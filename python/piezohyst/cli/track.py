"""``piezohyst track``: closed-loop tracking on a stage."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from .common import (
    _atomic_savefig,
    _Fail,
    _Parser,
)

if TYPE_CHECKING:
    from ..control.simulation import ControllerLike
    from ..models.model import HysteresisModel
    from ..plant.stage import Stage

_CONTROLLERS = ("open-loop", "pid", "inverse", "smc", "smc-cemf", "absmc")


_REFERENCES = ("sine", "triangle", "variable-sine")


def _track_parser(sub: argparse._SubParsersAction[_Parser]) -> None:
    t = sub.add_parser(
        "track",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        help="simulate a controller tracking a reference on a stage (default: the virtual stage)",
        description=(
            "Run one controller in closed loop on a stage (amplifier, sensor noise, quantization and delay\n"
            "included) and print the tracking metrics: RMSE and max error (um and % of range), seed-2-style\n"
            "normalized errors, linearity error. Controllers: open-loop (static inverse gain), pid,\n"
            "inverse (exact inverse of a hysteresis model, with a one-sample lead), smc / smc-cemf (seed 1,\n"
            "Case 1 / Case 2, on the stage's own CEMF parameters), absmc (seed 2, behind the inverse).\n"
            "inverse and absmc use --model, or identify an MPI model from a simulated measurement first."
        ),
        epilog=(
            "examples:\n"
            "  piezohyst track --controller smc-cemf --reference triangle --freq 5 --amp 5 --offset 7\n"
            "  piezohyst track --controller absmc --reference sine --freq 80 --amp 8 --offset 9 --json\n\n"
            "exit status: 0 on success, 2 on bad input (one line on stderr naming the argument), 3 when\n"
            "--model looks like a model of another actuator: over the amplifier's voltage range its output\n"
            "span is off the stage's by more than 3x, or its output unit is not m (the run is still made)."
        ),
    )
    t.add_argument("--stage", metavar="FILE", help="stage file (JSON; default: the built-in virtual stage)")
    t.add_argument("--controller", required=True, choices=_CONTROLLERS, help="controller kind")
    t.add_argument("--reference", default="sine", choices=_REFERENCES, help="reference kind (default sine)")
    t.add_argument("--freq", type=float, default=10.0, help="reference frequency, Hz (default 10)")
    t.add_argument("--amp", type=float, default=5.0, help="reference amplitude, um (default 5)")
    t.add_argument("--offset", type=float, default=8.0, help="reference centre, um (default 8)")
    t.add_argument("--duration", type=float, default=1.0, help="seconds (default 1)")
    t.add_argument("--skip", type=float, default=0.2, help="seconds left out of the metrics (default 0.2)")
    t.add_argument("--model", metavar="MODEL.json", help="hysteresis model file for inverse / absmc")
    t.add_argument("--seed", type=int, default=0, help="sensor-noise seed (default 0)")
    t.add_argument("--json", action="store_true", help="print the metrics as JSON")
    t.add_argument("--plot", metavar="FILE.png", help="write the tracking figure (not overwritten without --force)")
    t.add_argument("--force", action="store_true", help="overwrite --plot")


#: Longest `piezohyst track` run, samples (~1 GB of recorded signals).
_TRACK_MAX_SAMPLES = 10_000_000


def _build_controller(kind: str, stage: Stage, model_file: str | None) -> ControllerLike:
    """The controller ``kind`` of ``piezohyst track`` designed for ``stage`` (shared with ``piezohyst
    robustness``): inverse and absmc behind the hysteresis model file ``model_file``, or an MPI model
    identified from a simulated measurement of ``stage``."""
    import numpy as np

    from ..control.controllers import ABSMC, PID, SMC, Compensated, InverseFeedforward, OpenLoop, VelocityObserver

    fs = 1.0 / stage.sample_time

    def hysteresis_model() -> HysteresisModel:
        if model_file:
            from ..models.model import HysteresisModel, load_model

            loaded = load_model(model_file)
            if not isinstance(loaded, HysteresisModel):
                raise _Fail(
                    f"--model = '{model_file}' is a {loaded.kind} model, not a hysteresis model of the stage's "
                    f"actuator (pi, gpi/mpi, rdpi, preisach, boucwen, ...)"
                )
            return loaded
        from ..identify.core import identify_mpi

        t = np.arange(int(2.0 * fs)) / fs
        u = 75 - 75 * np.clip(1 - 0.5 * t, 0.2, 1.0) * np.cos(2 * np.pi * 5 * t)
        x = stage.simulate(u).position
        from ..models.model import HysteresisModel

        model = identify_mpi(u[:-1], x[1:], operators=9).model
        assert isinstance(model, HysteresisModel)  # an MPI model
        return model

    c: OpenLoop | PID | SMC | InverseFeedforward | Compensated
    if kind == "open-loop":
        c = OpenLoop()
    elif kind == "pid":
        c = PID(kp=2e6, ki=2e9)
    elif kind in ("smc", "smc-cemf"):
        c = SMC(
            stage.params, kp=1e6, kv=2e3, ks=20.0, phi=0.01, cemf=kind == "smc-cemf", observer=VelocityObserver(300.0)
        )
    elif kind == "inverse":
        c = InverseFeedforward(hysteresis_model(), c1=stage.sample_time)
    else:
        c = Compensated(ABSMC.linearized(2000.0, 0.7, c1=2e3, lam=2e3, ks=5e3, gamma_d=1e4), hysteresis_model())
    return c


def _track(args: argparse.Namespace) -> int:
    from ..control.tuning import track
    from ..plant.stage import Stage, virtual_stage
    from ..signals import references as refs

    stage = Stage.from_file(args.stage) if args.stage else virtual_stage()
    fs = 1.0 / stage.sample_time
    for name in ("freq", "amp", "duration"):
        if not getattr(args, name) > 0:
            raise _Fail(f"--{name} = {getattr(args, name)} must be > 0")
    if args.duration * fs > _TRACK_MAX_SAMPLES:
        raise _Fail(
            f"--duration = {args.duration:g} s is {args.duration * fs:.4g} samples at {fs:g} Hz; piezohyst track "
            f"runs at most {_TRACK_MAX_SAMPLES:.0e} (use piezohyst.closed_loop from Python for longer runs)"
        )
    amp, off = args.amp * 1e-6, args.offset * 1e-6
    if args.reference == "sine":
        _, ref = refs.sine(args.freq, amp, args.duration, fs, offset=off)
    elif args.reference == "triangle":
        _, ref = refs.triangle(args.freq, amp, args.duration, fs, offset=off)
    else:
        _, ref = refs.variable_amplitude_sine(args.freq, amp, args.duration, fs, offset=off)
    if args.plot and Path(args.plot).exists() and not args.force:
        raise _Fail(f"--plot {args.plot} exists; pass --force to overwrite it")

    kind = args.controller
    c = _build_controller(kind, stage, args.model)
    foreign = _foreign_model(args.model, stage) if args.model and kind in ("inverse", "absmc") else None
    res = track(c, ref, stage=stage, rng=args.seed, skip=args.skip)
    m = res.metrics
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        fig = res.plot(zoom=(args.skip, args.skip + min(0.5 / args.freq, args.duration - args.skip)))
        _atomic_savefig(fig, args.plot)
    if args.json:
        doc = {"controller": kind, "reference": args.reference, "freq_hz": args.freq, "metrics": m}
        if foreign is not None:
            doc["model_check"] = foreign
        print(json.dumps(doc, indent=2))
        return _distrust(foreign)
    print(
        f"{kind} tracking a {args.freq:g} Hz {args.reference} ({args.amp:g} um around {args.offset:g} um), "
        f"{args.duration:g} s, metrics after {args.skip:g} s"
    )
    print(f"  RMSE          {m['rmse'] * 1e6:9.4f} um  ({m['rmse_percent']:.3f} % of range)")
    print(f"  max error     {m['max_error'] * 1e6:9.4f} um  ({m['max_error_percent']:.3f} % of range)")
    print(f"  normalized    max {m['normalized_max_error']:.4f}, rms {m['normalized_rms_error']:.4f}")
    print(f"  linearity     {m['linearity_error']:9.3f} %")
    return _distrust(foreign)


def _foreign_model(path: str, stage: Stage) -> dict[str, object] | None:
    """Whether the model file looks like a model of another actuator than ``stage``: its output
    unit is not m, or over a slow 0 → v_max → 0 V sweep its output span is off the stage's by
    more than 3x. ``None`` when it fits."""
    import numpy as np

    from ..models.model import load_model

    model = load_model(path)
    fs = 1.0 / stage.sample_time
    n = max(int(0.1 * fs), 50)
    hi = stage.amplifier.v_max
    u = np.concatenate([np.linspace(0.0, hi, n), np.linspace(hi, 0.0, n)])
    span_stage = float(np.ptp(stage.simulate(u).position))
    span_model = float(np.ptp(model.simulate(u)))
    ratio = span_model / span_stage if span_stage > 0 else float("inf")
    unit = model.units.get("output", "")
    reasons = []
    if unit and unit != "m":
        reasons.append(f"its output unit is {unit!r}, the stage's position is in m")
    if not 1 / 3 <= ratio <= 3:
        reasons.append(
            f"over 0..{hi:g} V its output spans {span_model:.4g}, the stage's position {span_stage:.4g} m "
            f"({ratio:.3g}x)"
        )
    if not reasons:
        return None
    return {"foreign": True, "ratio": ratio, "reasons": reasons}


def _distrust(foreign: dict[str, object] | None) -> int:
    if foreign is None:
        return 0
    reasons = foreign["reasons"]
    assert isinstance(reasons, list)
    print(
        "piezohyst track: not trustworthy: --model looks like a model of another actuator: " + "; ".join(reasons),
        file=sys.stderr,
    )
    return 3
