"""``piezohyst simulate`` for a multi-channel (MIMO) model: U (N, nu) in, YHAT (N, ny) out, the
initial state set from a stretch of measured output (``--init-output Y0``) through the model's
own estimator.

The model is duck-typed (:class:`MimoSimulator`): the MIMO model class of ``piezohyst.models``
and anything else with ``nu``, ``ny`` and ``simulate(u, init_output=y0)`` simulate here.
Imports stay lazy: the whole call — interpreter start included — stays well under a second
for 8192 samples.
"""

from __future__ import annotations

import argparse
import io
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from ..outputs import write_atomic
from .common import _existing_file, _Fail

if TYPE_CHECKING:
    from .common import FloatArray

#: The output file types --out writes for a MIMO model.
OUT_SUFFIXES = (".npy", ".npz", ".csv")


@runtime_checkable
class MimoSimulator(Protocol):
    """What ``simulate`` needs of a multi-channel model (:class:`piezohyst.models.mimo.MimoModel`)."""

    @property
    def nu(self) -> int: ...  # pragma: no cover - protocol

    @property
    def ny(self) -> int: ...  # pragma: no cover - protocol

    def simulate(self, u: Any, *, init_output: Any = None) -> Any: ...  # pragma: no cover - protocol


def is_mimo(model: object) -> bool:
    """Whether ``model`` is a multi-channel model (it has ``nu`` and ``ny``)."""
    return hasattr(model, "nu") and hasattr(model, "ny") and callable(getattr(model, "simulate", None))


def run_mimo(model: MimoSimulator, u: FloatArray, y0: FloatArray | None) -> FloatArray:
    """The model's output ``(N, ny)`` for ``u`` ``(N, nu)``, its initial state set by its own
    estimator from the first ``M`` measured outputs ``y0`` ``(M, ny)`` (with ``u``), else by
    its default (rest, or the periodic steady state the model file asks for)."""
    import numpy as np

    y = np.asarray(model.simulate(u, init_output=y0), dtype=np.float64)
    if y.shape != (u.shape[0], model.ny):
        raise _Fail(f"the model returned shape {y.shape}, expected ({u.shape[0]}, {model.ny})")
    return y


def _label(model: Any) -> str:
    """``mimo (lfr)`` for the library's class, else the model's ``kind`` or class name."""
    structure = getattr(model, "structure", None)
    if isinstance(structure, str):
        return f"mimo ({structure})"
    return str(getattr(model, "kind", type(model).__name__))


def _array_bytes(write: Any) -> bytes:
    buf = io.BytesIO()
    write(buf)
    return buf.getvalue()


def _csv_text(y: FloatArray) -> str:
    ny = y.shape[1]
    lines = [",".join(f"y{j}" for j in range(ny))]
    lines += [",".join(map(repr, row)) for row in y.tolist()]  # repr: reads back bit for bit
    return "\n".join(lines) + "\n"


def simulate_mimo(args: argparse.Namespace, model: Any, model_path: Path, input_path: Path, out: Path | None) -> None:
    """The MIMO branch of ``piezohyst simulate`` (``model`` already read and checked)."""
    import numpy as np

    from ..errors import PiezohystError
    from ..signals.multichannel import read_channels

    for flag, value in (
        ("--output", args.output),
        ("--time", args.time),
        ("--dataset", args.dataset),
        ("--rows", args.rows),
    ):
        if value is not None:
            raise _Fail(f"{flag} = {value!r} applies to single-channel models; MODEL = '{model_path}' is multi-channel")
    if args.lag or args.score_from:
        raise _Fail("--lag / --score-from apply to single-channel models with --output; MODEL is multi-channel")
    nu, ny = int(model.nu), int(model.ny)
    key = args.input if isinstance(args.input, str) and args.input else None
    try:
        u = read_channels(input_path, "U", key=key)
    except (PiezohystError, FileNotFoundError) as e:
        raise _Fail(f"INPUT = '{input_path}': {e}") from None
    if u.shape[1] != nu:
        raise _Fail(
            f"INPUT = '{input_path}': U has shape {u.shape}, the model has {nu} inputs: expected ({u.shape[0]}, {nu})"
        )
    y0 = None
    init_path = None
    if args.init_output is not None:
        init_path = _existing_file(args.init_output, "--init-output")
        try:
            y0 = read_channels(init_path, "Y0")
        except (PiezohystError, FileNotFoundError) as e:
            raise _Fail(f"--init-output = '{init_path}': {e}") from None
        if y0.shape[1] != ny:
            raise _Fail(
                f"--init-output = '{init_path}': Y0 has shape {y0.shape}, the model has {ny} outputs: "
                f"expected (M, {ny})"
            )
        if y0.shape[0] > u.shape[0]:
            raise _Fail(
                f"--init-output = '{init_path}': Y0 has {y0.shape[0]} samples, more than U's {u.shape[0]}: "
                "Y0 is the first M measured outputs of the same record"
            )
    suffix = ".csv" if out is None else out.suffix.lower()
    if suffix not in OUT_SUFFIXES:
        raise _Fail(f"--out = '{out}': a multi-channel output is written as {' '.join(OUT_SUFFIXES)}, not {suffix!r}")
    if args.json and out is None:
        raise _Fail("--json prints a summary on standard output; give --out FILE for the output")

    t0 = time.perf_counter()
    try:
        y = run_mimo(model, u, y0)
    except _Fail:
        raise
    except (ValueError, TypeError) as e:
        raise _Fail(f"INPUT = '{input_path}': {e}") from None
    wall = time.perf_counter() - t0
    if not np.all(np.isfinite(y)):
        k = int(np.argwhere(~np.isfinite(y))[0][0])
        raise _Fail(f"the simulation diverged: YHAT[{k}] is not finite (an unstable model or an input out of range)")

    inputs = {"MODEL": model_path, "INPUT": input_path, "--init-output": init_path}
    if out is None:
        sys.stdout.write(_csv_text(y))
        return
    if suffix == ".npy":
        write_atomic(out, _array_bytes(lambda b: np.save(b, y)), overwrite=args.force, name="--out", inputs=inputs)
    elif suffix == ".npz":
        data = _array_bytes(lambda b: np.savez(b, y=y))
        write_atomic(out, data, overwrite=args.force, name="--out", inputs=inputs)
    else:
        write_atomic(out, _csv_text(y), overwrite=args.force, name="--out", inputs=inputs)
    units = getattr(model, "units", None)
    units = {k: v for k, v in units.items() if isinstance(v, str)} if isinstance(units, dict) else {}
    summary = {
        "out": str(out),
        "model": _label(model),
        "model_file": str(model_path),
        "input_file": str(input_path),
        "init_output_file": None if init_path is None else str(init_path),
        "samples": int(u.shape[0]),
        "init_samples": 0 if y0 is None else int(y0.shape[0]),
        "n_inputs": nu,
        "n_outputs": ny,
        "shape": [int(k) for k in y.shape],
        "wall_time_s": wall,
        "output": {
            "min": [float(v) for v in y.min(axis=0)],
            "max": [float(v) for v in y.max(axis=0)],
            "rms": [float(v) for v in np.sqrt(np.mean(y**2, axis=0))],
        },
        "units": {"input": units.get("input", "V"), "output": units.get("output", "m")},
    }
    if args.json:
        print(json.dumps(summary, indent=2, allow_nan=False))
        return
    init = f", state from the first {y0.shape[0]} outputs of {init_path}" if y0 is not None else ", from rest"
    print(
        f"{summary['model']} simulated on {u.shape[0]} samples x {nu} inputs of {input_path.name}{init} "
        f"in {wall:.3g} s -> {out} ({u.shape[0]}, {ny})"
    )
