"""``piezohyst track``: closed-loop tracking on a stage."""

from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING

from .common import (
    _atomic_savefig,
    _count_arg,
    _Fail,
    _Parser,
    _quantity,
    _writable,
)

if TYPE_CHECKING:
    from ..control.simulation import ControllerLike
    from ..models.model import HysteresisModel
    from ..plant.stage import Stage
    from ..signals.metrics import FloatArray

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
            "  piezohyst track --controller absmc --reference sine --freq 80Hz --amp 8um --offset 9um --json\n\n"
            "units: --freq, --amp, --offset, --duration and --skip take a unit suffix (80Hz, 0.1kHz, 8um,\n"
            "0.008mm, 500ms); a bare number is in Hz, um, um, s and s as before. Inside, and in --json,\n"
            "everything is SI: freq_hz, amplitude_m, offset_m, duration_s, skip_s, and the metrics with\n"
            'their units under "units" (rmse and max_error in m, the rest in % of range or ratios);\n'
            "the text output prints um.\n\n"
            "exit status: 0 on success, 2 on bad input (one line on stderr naming the argument), 3 when\n"
            "--model looks like a model of another actuator: over the amplifier's voltage range its output\n"
            "span is off the stage's by more than 3x or strays from the stage's position by more than 10 %\n"
            "of its range (RMS), the reference is outside the model's output, or its output unit is not m\n"
            "(input unit not V); the run is still made, the diagnosis names units and both ranges. --model\n"
            "is read and checked with every controller (a warning when the controller does not use it)."
        ),
    )
    t.add_argument("--stage", metavar="FILE", help="stage file (JSON; default: the built-in virtual stage)")
    t.add_argument("--controller", required=True, choices=_CONTROLLERS, help="controller kind")
    t.add_argument("--reference", default="sine", choices=_REFERENCES, help="reference kind (default sine)")
    t.add_argument(
        "--freq", type=_quantity("Hz"), default=10.0, help="reference frequency; a bare number is in Hz (default 10)"
    )
    t.add_argument(
        "--amp",
        type=_quantity("um"),
        default=5e-6,
        help="reference amplitude; a bare number is in um, or give a unit: 5um, 0.005mm, 5000nm (default 5 um)",
    )
    t.add_argument(
        "--offset", type=_quantity("um"), default=8e-6, help="reference centre; a bare number is in um (default 8 um)"
    )
    t.add_argument(
        "--duration", type=_quantity("s"), default=1.0, help="run length; a bare number is in s, or 500ms (default 1 s)"
    )
    t.add_argument(
        "--skip",
        type=_quantity("s"),
        default=0.2,
        help="time left out of the metrics; a bare number is in s (default 0.2 s)",
    )
    t.add_argument("--model", metavar="MODEL.json", help="hysteresis model file for inverse / absmc")
    t.add_argument("--seed", type=_count_arg, default=0, help="sensor-noise seed (default 0)")
    t.add_argument("--json", action="store_true", help="print the metrics as JSON")
    t.add_argument("--plot", metavar="FILE.png", help="write the tracking figure (not overwritten without --force)")
    t.add_argument("--force", action="store_true", help="overwrite --plot")


#: The unit of each number of ``track --json``'s ``metrics`` (SI; ``%`` of the reference's range;
#: ``1`` for a ratio).
_METRIC_UNITS = {
    "rmse": "m",
    "max_error": "m",
    "rmse_percent": "%",
    "max_error_percent": "%",
    "normalized_max_error": "1",
    "normalized_rms_error": "1",
    "linearity_error": "%",
}

#: Longest `piezohyst track` run, samples (~1 GB of recorded signals).
_TRACK_MAX_SAMPLES = 10_000_000


def _build_controller(
    kind: str, stage: Stage, model_file: str | None, *, model: HysteresisModel | None = None
) -> ControllerLike:
    """The controller ``kind`` of ``piezohyst track`` designed for ``stage`` (shared with ``piezohyst
    robustness``): inverse and absmc behind ``model`` (already read and checked) or the hysteresis
    model file ``model_file``, else an MPI model identified from a simulated measurement of ``stage``."""
    import numpy as np

    from ..control.controllers import ABSMC, PID, SMC, Compensated, InverseFeedforward, OpenLoop, VelocityObserver

    fs = 1.0 / stage.sample_time

    def hysteresis_model() -> HysteresisModel:
        if model is not None:
            return model
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

        fitted = identify_mpi(u[:-1], x[1:], operators=9).model
        assert isinstance(fitted, HysteresisModel)  # an MPI model
        return fitted

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
    from ..errors import ParameterError
    from ..plant.stage import Stage, virtual_stage
    from ..signals import references as refs

    stage = Stage.from_file(args.stage) if args.stage else virtual_stage()
    fs = 1.0 / stage.sample_time
    for name, unit, scale in (("freq", "Hz", 1.0), ("amp", "um", 1e6), ("duration", "s", 1.0)):
        if not getattr(args, name) > 0:
            value = float(f"{getattr(args, name) * scale:.12g}")  # in the unit of a bare number
            raise _Fail(f"--{name} = {value} must be > 0 ({unit})")
    if args.duration * fs > _TRACK_MAX_SAMPLES:
        raise _Fail(
            f"--duration = {args.duration:g} s is {args.duration * fs:.4g} samples at {fs:g} Hz; piezohyst track "
            f"runs at most {_TRACK_MAX_SAMPLES:.0e} (use piezohyst.closed_loop from Python for longer runs)"
        )
    amp, off = args.amp, args.offset  # SI (m): parsed by _quantity
    if args.reference == "sine":
        _, ref = refs.sine(args.freq, amp, args.duration, fs, offset=off)
    elif args.reference == "triangle":
        _, ref = refs.triangle(args.freq, amp, args.duration, fs, offset=off)
    else:
        _, ref = refs.variable_amplitude_sine(args.freq, amp, args.duration, fs, offset=off)
    if args.plot:
        _writable(args.plot, "--plot", args.force, {"--stage": args.stage, "--model": args.model})

    kind = args.controller
    given: HysteresisModel | None = None
    if args.model:  # read and validated whatever the controller: a broken file is an error
        from ..models.model import HysteresisModel, load_model

        loaded = load_model(args.model)
        if kind not in ("inverse", "absmc"):
            print(
                f"piezohyst track: warning: --model = '{args.model}' is not used by --controller {kind} "
                "(only inverse and absmc use a model)",
                file=sys.stderr,
            )
        elif not isinstance(loaded, HysteresisModel):
            raise _Fail(
                f"--model = '{args.model}' is a {loaded.kind} model, not a hysteresis model of the stage's "
                f"actuator (pi, gpi/mpi, rdpi, preisach, boucwen, ...)"
            )
        else:
            given = loaded
    foreign = None if given is None else _foreign_model(given, args.model, stage, ref)

    c = _build_controller(kind, stage, None, model=given)
    try:
        res = track(c, ref, stage=stage, rng=args.seed, skip=args.skip)
    except ParameterError as e:  # e.g. the inverse's limits: no output range at the amplifier limits
        if foreign is None:
            raise
        reasons = foreign["reasons"]
        assert isinstance(reasons, list)
        raise _Fail(
            f"--model = '{args.model}' cannot drive this stage ({e}): it looks like a model of another "
            f"actuator: {'; '.join(reasons)}"
        ) from None
    m = res.metrics
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        fig = res.plot(zoom=(args.skip, args.skip + min(0.5 / args.freq, args.duration - args.skip)))
        _atomic_savefig(fig, args.plot, "--plot", args.force)
    if args.json:
        doc = {
            "controller": kind,
            "reference": args.reference,
            "freq_hz": args.freq,
            "amplitude_m": amp,
            "offset_m": off,
            "duration_s": args.duration,
            "skip_s": args.skip,
            "metrics": m,
            "units": _METRIC_UNITS,
        }
        if foreign is not None:
            doc["model_check"] = foreign
        print(json.dumps(doc, indent=2))
        return _distrust(foreign)
    print(
        f"{kind} tracking a {args.freq:g} Hz {args.reference} ({amp * 1e6:g} um around {off * 1e6:g} um), "
        f"{args.duration:g} s, metrics after {args.skip:g} s"
    )
    print(f"  RMSE          {m['rmse'] * 1e6:9.4f} um  ({m['rmse_percent']:.3f} % of range)")
    print(f"  max error     {m['max_error'] * 1e6:9.4f} um  ({m['max_error_percent']:.3f} % of range)")
    print(f"  normalized    max {m['normalized_max_error']:.4f}, rms {m['normalized_rms_error']:.4f}")
    print(f"  linearity     {m['linearity_error']:9.3f} %")
    return _distrust(foreign)


#: How far (RMS, in % of the stage's range) a model's output over the amplifier's voltage sweep
#: may stray from the stage's position before it is "a model of another actuator". Models
#: identified on the virtual stage stray 0.44 % (mpi), 0.49 % (pi), 0.98 % (preisach); 10 %
#: leaves room for creep and dynamics a model does not carry, and flags a gain off by 1.2x
#: (12.3 %) or an offset of a tenth of the stroke.
_MISMATCH_PERCENT = 10.0


def _foreign_model(model: HysteresisModel, path: str, stage: Stage, ref: FloatArray) -> dict[str, object] | None:
    """Whether the model looks like a model of another actuator than ``stage``: its output unit
    is not m or its input unit not V; over a slow 0 → v_max → 0 V sweep its output span is off
    the stage's by more than 3x, or its output strays from the stage's position by more than
    :data:`_MISMATCH_PERCENT` % of the stage's range (a gain, an offset, another unit); or the
    reference lies outside what the model can produce over the amplifier's range. ``None``
    when it fits. The diagnosis names the units and both output ranges."""
    import numpy as np

    fs = 1.0 / stage.sample_time
    n = max(int(0.1 * fs), 50)
    hi = stage.amplifier.v_max
    u = np.concatenate([np.linspace(0.0, hi, n), np.linspace(hi, 0.0, n)])
    x_stage = stage.simulate(u).position
    x_model = model.simulate(u)
    span_stage = float(np.ptp(x_stage))
    span_model = float(np.ptp(x_model))
    ratio = span_model / span_stage if span_stage > 0 else float("inf")
    scale = max(float(np.max(np.abs(x_stage))), float(np.max(np.abs(x_model))), 1e-300)  # no overflow
    stray = (
        100.0 * float(np.sqrt(np.mean(((x_model - x_stage) / scale) ** 2))) * scale / span_stage
        if span_stage > 0
        else float("inf")
    )
    unit_out = model.units.get("output", "")
    unit_in = model.units.get("input", "")
    reasons = []
    if unit_out and unit_out != "m":
        reasons.append(f"its output unit is {unit_out!r}, the stage's position is in m")
    if unit_in and unit_in != "V":
        reasons.append(f"its input unit is {unit_in!r}, the stage's amplifier takes V")
    m_lo, m_hi, s_lo, s_hi = float(x_model.min()), float(x_model.max()), float(x_stage.min()), float(x_stage.max())
    ranges = (
        f"over 0..{hi:g} V its output spans [{m_lo:.4g}, {m_hi:.4g}], the stage's position [{s_lo:.4g}, {s_hi:.4g}] m"
    )
    if not 1 / 3 <= ratio <= 3:
        reasons.append(f"{ranges} (span {span_model:.4g} vs {span_stage:.4g}, {ratio:.3g}x)")
    elif stray > _MISMATCH_PERCENT:
        reasons.append(f"{ranges}: they differ by {stray:.3g} % of the stage's range (RMS)")
    r_lo, r_hi = float(ref.min()), float(ref.max())
    slack = 0.05 * (m_hi - m_lo)
    if r_lo < m_lo - slack or r_hi > m_hi + slack:
        reasons.append(
            f"the reference [{r_lo:.4g}, {r_hi:.4g}] m is outside the model's output [{m_lo:.4g}, {m_hi:.4g}]"
        )
    if not reasons:
        return None
    if not unit_out and not any("unit" in r for r in reasons):
        reasons.append("the model file gives no output unit")
    return {
        "foreign": True,
        "ratio": ratio,
        "mismatch_percent": stray,
        "units": {"input": unit_in, "output": unit_out},
        "model_output_range": [m_lo, m_hi],
        "stage_position_range": [s_lo, s_hi],
        "reasons": reasons,
        "model": path,
    }


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
