"""Export identified models and tuned controllers to C (docs/spec.md §9): the embedded runtime is
``libpiezohyst`` (``crates/capi``, header ``crates/capi/include/piezohyst.h``), which runs
the same Rust code as Python, so a model or controller exported here gives in C the numbers
it gives in Python, bit for bit.

* :func:`save_controller` writes a tuned controller as a small JSON file (the flat
  parameter array the core runs, with names, plus the inverse model and ILC settings and the
  stage's sample time); :func:`load_controller` reads it back as a controller usable in
  :func:`piezohyst.closed_loop` and :func:`piezohyst.track`.
* :func:`export_c` (``piezohyst export-c MODEL.json [CONTROLLER.json] --out DIR``) writes C
  initializers (``piezohyst_model.h/.c``, ``piezohyst_controller.h/.c``), a copy of
  ``piezohyst.h`` and a minimal real-time loop ``example.c`` that compiles with ``cc``
  against the library.

Controller file (``"format": "piezohyst-controller"``, ``schema_version`` 1)::

    {"schema_version": 1, "format": "piezohyst-controller", "kind": "smc",
     "description": "SMC(...)",
     "params": {"M": ..., "B": ..., ..., "u_min": -20.0, "u_max": 150.0},
     "inverse": null | {"family": "gpi", "dims": [9, 0, 0, 0], "params": [...],
                        "u_min": -20.0, "u_max": 150.0},
     "ilc": null | {"period": 1000, "gain": 0.3, "forgetting": 1.0, "lead": 3, "delay": 1},
     "stage": {"sample_time": 1e-4, "sensor_delay": 1, "amplifier_v_min": -20.0,
               "amplifier_v_max": 150.0}}

``params`` are exactly ``controller.core(stage)[1]`` in order (names in
:data:`CONTROLLER_PARAMS`); floats are written so they read back bit for bit.
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, NotRequired, Protocol, TypeAlias, TypedDict

import numpy as np
import numpy.typing as npt

from .. import _core
from .._io import PathLike, json_text, load_json_file, malformed_as, write_atomic
from ..control.controllers import CoreSpec, FloatArray, IlcSpec, Limits, PackedController, is_controller
from ..errors import ParameterError, ParameterTypeError
from ..outputs import output_set

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..models.model import HysteresisModel
    from ..plant.stage import Stage

__all__ = [
    "CONTROLLER_KINDS",
    "CONTROLLER_PARAMS",
    "CONTROLLER_SCHEMA_VERSION",
    "EXPORT_FILES",
    "FAMILY_CODES",
    "ExportedController",
    "controller_from_dict",
    "controller_to_dict",
    "export_c",
    "header_path",
    "library_path",
    "load_controller",
    "row_names",
    "save_controller",
]

#: ``PhsFamily`` and ``PhsControllerKind`` codes of the C library (the core's layout table).
FAMILY_CODES, CONTROLLER_KINDS = _core.layout_codes()
#: Names of the flat parameters of each controller kind (``controller.core(stage)[1]``;
#: the core's layout table, ``_core.controller_layout``).
CONTROLLER_PARAMS: dict[str, tuple[str, ...]] = {
    kind: tuple(_core.controller_layout(kind)["slots"]) for kind in CONTROLLER_KINDS
}
#: Every file :func:`export_c` may write into its folder (a set: a new export replaces them all).
EXPORT_FILES = (
    "piezohyst_model.h",
    "piezohyst_model.c",
    "piezohyst_controller.h",
    "piezohyst_controller.c",
    "example.c",
    "piezohyst.h",
)
#: Version of the controller-file layout.
CONTROLLER_SCHEMA_VERSION = 1
_FORMAT = "piezohyst-controller"
_ILC_FIELDS = ("period", "gain", "forgetting", "lead", "delay")

#: ``(family, dims, row, u_min, u_max)`` of the inverse model an exported controller acts behind.
ExportedInverse: TypeAlias = tuple[str, Sequence[int], Sequence[float], float, float]


class _HasSampleTime(Protocol):
    """What an exported controller needs of a stage: its sample time (s)."""

    @property
    def sample_time(self) -> float: ...


# --------------------------------------------------------------------------------------------
# controller files


@dataclass(frozen=True, eq=False)
class ExportedController:
    """A controller read from a controller file: exactly the flat description the core runs.
    It works wherever a controller does (:func:`piezohyst.closed_loop`, :func:`piezohyst.track`)
    on a stage with the sample time it was saved for.

    Parameters
    ----------
    kind : str
        The controller kind (one of ``CONTROLLER_KINDS``).
    params : ndarray
        The flat parameters, in the layout ``CONTROLLER_PARAMS[kind]``.
    inverse : tuple, optional
        ``(family, dims, row, u_min, u_max)`` of the inverse model it acts behind.
    ilc : tuple, optional
        The iterative learning control's settings.
    sample_time : float, optional
        The sample time it was saved for, s.
    description : str, optional
        What the controller was saved from.

    Examples
    --------
    >>> import piezohyst as ph
    >>> from piezohyst.export.c import ExportedController
    >>> stage = ph.virtual_stage()
    >>> pid = ph.PID(kp=1e6, ki=5e9)
    >>> c = ExportedController("pid", pid.core(stage)[1], sample_time=stage.sample_time)
    >>> ref = [5e-6] * 200
    >>> a = ph.closed_loop(stage, c, ref, rng=1).position
    >>> b = ph.closed_loop(stage, pid, ref, rng=1).position
    >>> bool((a == b).all())                                # runs as the PID it came from
    True
    """

    kind: str
    params: FloatArray
    inverse: ExportedInverse | None = None
    ilc: IlcSpec | None = None
    sample_time: float = 1e-4
    description: str = ""

    #: the saved description does not say; the loop then passes the derivatives
    uses_reference_derivatives = True

    def core(self, stage: _HasSampleTime, *, limits: Limits | None = None) -> CoreSpec:
        """The description the core runs, as saved, for ``stage`` (checked: the same sample
        time).

        Parameters
        ----------
        stage : Stage
            A stage with the controller's sample time.
        limits : Limits, optional
            Refused: an exported controller is already complete.

        Returns
        -------
        tuple
            ``(kind, params, inverse, ilc)``.

        Examples
        --------
        >>> import piezohyst as ph
        >>> from piezohyst.export.c import ExportedController
        >>> stage = ph.virtual_stage()
        >>> c = ExportedController("pid", ph.PID(kp=1e6, ki=5e9).core(stage)[1], sample_time=stage.sample_time)
        >>> kind, params, inverse, ilc = c.core(stage)
        >>> kind, params[:2].tolist(), inverse, ilc
        ('pid', [1000000.0, 5000000000.0], None, None)
        """
        if limits is not None:
            raise ParameterTypeError("an exported controller cannot be wrapped again (it is already complete)")
        ts = float(stage.sample_time)
        if abs(ts - self.sample_time) > 1e-12 * self.sample_time:
            raise ParameterError(
                f"stage.sample_time = {ts} s differs from the controller's sample_time = "
                f"{self.sample_time} s it was saved for"
            )
        inverse = (
            None
            if self.inverse is None
            else (
                self.inverse[0],
                list(self.inverse[1]),
                np.array(self.inverse[2], dtype=np.float64),
                self.inverse[3],
                self.inverse[4],
            )
        )
        return self.kind, self.params.copy(), inverse, self.ilc

    def __repr__(self) -> str:
        extra = (" behind an inverse" if self.inverse else "") + (" with ILC" if self.ilc else "")
        return f"ExportedController({self.kind}{extra}: {self.description or '...'})"


def _finite(x: object, name: str) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise ParameterError(f"{name} = {x!r} must be a number")
    v = float(x)
    if not math.isfinite(v):
        raise ParameterError(f"{name} = {v} is not finite")
    return v


def _count(x: object, name: str, minimum: int = 0) -> int:
    if isinstance(x, bool) or not isinstance(x, int) or x < minimum:
        raise ParameterError(f"{name} = {x!r} must be an integer >= {minimum}")
    return int(x)


def _validated(
    kind: str,
    params: npt.ArrayLike,
    inverse: tuple[str, Iterable[int], npt.ArrayLike, float, float] | None,
    ilc: IlcSpec | None,
) -> None:
    """Build the controller once in the core (raises ValueError naming the problem)."""
    spec: CoreSpec = (
        kind,
        np.ascontiguousarray(params, dtype=np.float64),
        None
        if inverse is None
        else (
            inverse[0],
            list(inverse[1]),
            np.ascontiguousarray(inverse[2], dtype=np.float64),
            float(inverse[3]),
            float(inverse[4]),
        ),
        ilc,
    )
    _core.controller_initial_state(spec, 0.0)


def controller_to_dict(controller: PackedController, stage: Stage) -> dict[str, Any]:
    """The controller file's content for ``controller`` on ``stage`` (see the module doc).

    Parameters
    ----------
    controller : controller configuration
        A piezohyst controller (:class:`~piezohyst.control.PID`, :class:`~piezohyst.control.SMC`, ...).
    stage : Stage
        The stage it runs on (sample time, sensor delay, amplifier limits).

    Returns
    -------
    dict

    Examples
    --------
    >>> import piezohyst as ph
    >>> from piezohyst.export import controller_to_dict
    >>> d = controller_to_dict(ph.PID(kp=2e6, ki=2e9), ph.virtual_stage())
    >>> d["format"], d["kind"], d["params"]["kp"], d["stage"]["sample_time"]
    ('piezohyst-controller', 'pid', 2000000.0, 0.0001)
    """
    if not is_controller(controller):
        raise ParameterTypeError(
            f"controller must be a piezohyst controller (OpenLoop, PID, SMC, ...), got {type(controller).__name__}"
        )
    kind, params, inverse, ilc = controller.core(stage)
    names = CONTROLLER_PARAMS[kind]
    values = [float(x) for x in np.asarray(params, dtype=np.float64)]
    if len(values) != len(names):
        raise ParameterError(f"controller {kind!r} gave {len(values)} parameters, expected {len(names)}")
    _validated(kind, values, inverse, ilc)
    d: dict[str, Any] = {
        "schema_version": CONTROLLER_SCHEMA_VERSION,
        "format": _FORMAT,
        "kind": kind,
        "description": repr(controller),
        "params": dict(zip(names, values, strict=False)),
        "inverse": None,
        "ilc": None,
        "stage": {
            "sample_time": float(stage.sample_time),
            "sensor_delay": int(stage.sensor.delay),
            "amplifier_v_min": float(stage.amplifier.v_min),
            "amplifier_v_max": float(stage.amplifier.v_max),
        },
    }
    if inverse is not None:
        family, dims, row, lo, hi = inverse
        d["inverse"] = {
            "family": family,
            "dims": [int(x) for x in dims],
            "params": [float(x) for x in np.asarray(row, dtype=np.float64)],
            "u_min": float(lo),
            "u_max": float(hi),
        }
    if ilc is not None:
        d["ilc"] = {
            "period": int(ilc[0]),
            "gain": float(ilc[1]),
            "forgetting": float(ilc[2]),
            "lead": int(ilc[3]),
            "delay": int(ilc[4]),
        }
    return d


def controller_from_dict(d: object) -> ExportedController:
    """Read a controller file's content (validated: the core builds it once).

    Parameters
    ----------
    d : dict
        A controller file's JSON object (:func:`controller_to_dict`).

    Returns
    -------
    ExportedController

    Examples
    --------
    >>> import piezohyst as ph
    >>> from piezohyst.export import controller_from_dict, controller_to_dict
    >>> c = controller_from_dict(controller_to_dict(ph.PID(kp=2e6, ki=2e9), ph.virtual_stage()))
    >>> c.kind, c.sample_time
    ('pid', 0.0001)
    """
    with malformed_as("the controller description"):
        return _controller_from_dict(d)


def _controller_from_dict(d: object) -> ExportedController:
    if not isinstance(d, dict):
        raise ParameterError(f"a controller description must be a JSON object, got {type(d).__name__}")
    if d.get("format") != _FORMAT:
        raise ParameterError(f"format = {d.get('format')!r} is not {_FORMAT!r} (is this a model file?)")
    version = d.get("schema_version")
    if type(version) is not int or version != CONTROLLER_SCHEMA_VERSION:  # true is not 1
        raise ParameterError(
            f"schema_version = {json_text(version)} is not supported (this version reads the integer "
            f"{CONTROLLER_SCHEMA_VERSION})"
        )
    kind = d.get("kind")
    if kind not in CONTROLLER_PARAMS:
        raise ParameterError(f"kind = {kind!r} is unknown; expected one of {', '.join(CONTROLLER_PARAMS)}")
    p = d.get("params")
    names = CONTROLLER_PARAMS[kind]
    if not isinstance(p, dict) or list(p) != list(names):
        got = list(p) if isinstance(p, dict) else p
        raise ParameterError(
            f"params of {kind!r} must be an object with the keys {list(names)} in this order, got {got!r}"
        )
    params = np.array([_finite(p[n], f"params.{n}") for n in names], dtype=np.float64)
    inverse: ExportedInverse | None = None
    inv = d.get("inverse")
    if inv is not None:
        if not isinstance(inv, dict):
            raise ParameterError("inverse must be null or an object {family, dims, params, u_min, u_max}")
        family = inv.get("family")
        if family not in FAMILY_CODES:
            raise ParameterError(f"inverse.family = {family!r} is unknown; expected one of {', '.join(FAMILY_CODES)}")
        dims = inv.get("dims")
        if not isinstance(dims, list):
            raise ParameterError(f"inverse.dims = {dims!r} must be a list of integers")
        dims_ = tuple(_count(x, f"inverse.dims[{i}]") for i, x in enumerate(dims))
        row = inv.get("params")
        if not isinstance(row, list):
            raise ParameterError("inverse.params must be a list of numbers")
        row_ = tuple(_finite(x, f"inverse.params[{i}]") for i, x in enumerate(row))
        inverse = (
            family,
            dims_,
            row_,
            _finite(inv.get("u_min"), "inverse.u_min"),
            _finite(inv.get("u_max"), "inverse.u_max"),
        )
    ilc: IlcSpec | None = None
    il = d.get("ilc")
    if il is not None:
        if not isinstance(il, dict) or set(il) != set(_ILC_FIELDS):
            raise ParameterError(f"ilc must be null or an object with the keys {list(_ILC_FIELDS)}")
        ilc = (
            _count(il["period"], "ilc.period", 1),
            _finite(il["gain"], "ilc.gain"),
            _finite(il["forgetting"], "ilc.forgetting"),
            _count(il["lead"], "ilc.lead"),
            _count(il["delay"], "ilc.delay"),
        )
    stage = d.get("stage")
    if not isinstance(stage, dict) or "sample_time" not in stage:
        raise ParameterError("stage must be an object with at least sample_time (s)")
    ts = _finite(stage["sample_time"], "stage.sample_time")
    if not ts > 0:
        raise ParameterError(f"stage.sample_time = {ts} must be > 0")
    try:
        _validated(kind, params, inverse, ilc)
    except ValueError as e:
        raise ParameterError(f"controller {kind!r} is not valid: {e}") from None
    params.setflags(write=False)
    return ExportedController(kind, params, inverse, ilc, ts, str(d.get("description", "")))


def save_controller(controller: PackedController, stage: Stage, path: PathLike, *, overwrite: bool = False) -> Path:
    """Write ``controller`` (as it runs on ``stage``) to a controller file, atomically; an
    existing file is kept unless ``overwrite``.

    Parameters
    ----------
    controller : controller configuration
        A piezohyst controller.
    stage : Stage
        The stage it runs on.
    path : str or os.PathLike
        The file to write (JSON).
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    pathlib.Path

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import piezohyst as ph
    >>> from piezohyst.export_c import save_controller, load_controller
    >>> stage = ph.virtual_stage()
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "pid.json"
    >>> _ = save_controller(ph.PID(kp=2e6, ki=2e9), stage, path)
    >>> c = load_controller(path)
    >>> c.kind, c.params.tolist() == ph.PID(kp=2e6, ki=2e9).core(stage)[1].tolist()
    ('pid', True)
    """
    text = json.dumps(controller_to_dict(controller, stage), indent=2, allow_nan=False) + "\n"
    return write_atomic(path, text, overwrite=overwrite)


def load_controller(path: PathLike) -> ExportedController:
    """Read a controller file written by :func:`save_controller` (``DataError`` naming the
    file if it is not one).

    Parameters
    ----------
    path : str or os.PathLike
        The controller file.

    Returns
    -------
    ExportedController
        Usable as a controller in :func:`piezohyst.closed_loop` and :func:`piezohyst.track`,
        and by :func:`export_c`.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import piezohyst as ph
    >>> from piezohyst.export import load_controller, save_controller
    >>> stage = ph.virtual_stage()
    >>> path = save_controller(ph.PID(kp=1e6, ki=5e9), stage, pathlib.Path(tempfile.mkdtemp()) / "pid.json")
    >>> ref = [5e-6] * 200
    >>> a = ph.closed_loop(stage, load_controller(path), ref, rng=1).position
    >>> b = ph.closed_loop(stage, ph.PID(kp=1e6, ki=5e9), ref, rng=1).position
    >>> bool((a == b).all())
    True
    """
    return load_json_file(path, "controller file", controller_from_dict)


# --------------------------------------------------------------------------------------------
# C export


def row_names(family: str, dims: Iterable[int]) -> list[str]:
    """Names of the slots of a model family's parameter row (the core's layout table,
    ``_core.family_layout``).

    Parameters
    ----------
    family : str
        The model family (one of ``FAMILY_CODES``).
    dims : iterable of int
        The family's dimensions, a model's ``dims`` (for ``"pi"``: the number of play
        operators, then the number of creep terms).

    Returns
    -------
    list of str

    Examples
    --------
    >>> from piezohyst.export.c import row_names
    >>> row_names("pi", [3, 0])                             # offset, thresholds, weights
    ['p0', 'r[0]', 'r[1]', 'r[2]', 'w[0]', 'w[1]', 'w[2]']
    >>> row_names("pi", [3, 2])[7:]                         # and two creep terms
    ['creep_ts', 'creep_tau[0]', 'creep_tau[1]', 'creep_c[0]', 'creep_c[1]']
    """
    if family not in FAMILY_CODES:
        raise ParameterError(f"family = {family!r} is unknown; expected one of {', '.join(FAMILY_CODES)}")
    return list(_core.family_layout(family, [int(x) for x in dims])["slots"])


def _repo_root() -> Path:
    return Path(__file__).resolve().parents[3]  # python/piezohyst/export/c.py -> the repository


def header_path() -> Path | None:
    """``piezohyst.h`` of the C library: the source tree's when piezohyst runs from one, else the
    copy the wheel ships (:func:`piezohyst.capi.header_path`).

    Returns
    -------
    pathlib.Path or None
        ``None`` when neither exists.

    Examples
    --------
    >>> from piezohyst.export.c import header_path
    >>> p = header_path()
    >>> p is None or (p.name == "piezohyst.h" and "phs_" in p.read_text())
    True
    """
    p = _repo_root() / "crates" / "capi" / "include" / "piezohyst.h"
    if p.is_file():
        return p
    from .. import capi

    try:
        return capi.header_path()
    except FileNotFoundError:
        return None


def library_path() -> Path | None:
    """The static library: the source tree's build ``target/release/libpiezohyst.a`` if it
    exists, else the copy the wheel ships (:func:`piezohyst.capi.library_path`).

    Returns
    -------
    pathlib.Path or None
        ``None`` when neither exists (a source tree not built with ``cargo build --release``).

    Examples
    --------
    >>> from piezohyst.export.c import library_path
    >>> p = library_path()
    >>> p is None or (p.name == "libpiezohyst.a" and p.is_file())
    True
    """
    p = _repo_root() / "target" / "release" / "libpiezohyst.a"
    if p.is_file():
        return p
    from .. import capi

    try:
        return capi.library_path(static=True)
    except FileNotFoundError:
        return None


#: Libraries the Rust static library needs from the system (``rustc --print native-static-libs``).
LINK_LIBS = "-lgcc_s -lutil -lrt -lpthread -lm -ldl -lc"


def _c_double(x: float) -> str:
    """An exact C99 literal (hex float) for a finite double."""
    x = float(x)
    if not math.isfinite(x):
        raise ParameterError(f"{x} is not finite and has no C literal")
    return x.hex()


def _c_parameter(x: float) -> str:
    """A parameter's C99 literal: exact hex for a finite double, ``INFINITY`` / ``-INFINITY``
    (``<math.h>``, a constant expression) for an infinite one (an open input range); NaN has
    none (``ParameterError``)."""
    x = float(x)
    if math.isinf(x):
        return "INFINITY" if x > 0 else "-INFINITY"
    return _c_double(x)


def _c_array(name: str, values: FloatArray, names: Sequence[str], indent: str = "    ") -> str:
    lines = [f"const double {name}[{len(values)}] = {{"]
    for i, (v, n) in enumerate(zip(values, names, strict=False)):
        comma = "," if i + 1 < len(values) else " "
        lines.append(f"{indent}{_c_parameter(v)}{comma}  /* [{i}] {n} = {float(v)!r} */")
    lines.append("};")
    return "\n".join(lines)


def _guard(name: str) -> str:
    return name.upper().replace(".", "_")


def _model_files(model: HysteresisModel, source: str) -> dict[str, str]:
    fam, dims, row = model.family, list(model.dims), model.to_row()
    n_params, n_core = _core.family_sizes(fam, dims)
    names = row_names(fam, dims)
    dims4 = ([*dims, 0, 0, 0, 0])[:4]
    # the scratch size is what phs_model_sizes reports: derived coefficients (Preisach prefix
    # sums, creep lag gains)
    scratch = int(_core.family_layout(fam, dims)["scratch_len"])
    omap = model.output_map
    delay = model.input_delay
    # the state: the core's, then (with a delay) the delay line and the samples since the start,
    # the layout of HysteresisModel.state
    n_state = n_core + (delay + 1 if delay else 0)
    drift_note = (
        " *\n * The model's drift (a trend of its training record's sensor, counted from that record's\n"
        " * start) is not exported: a real-time loop drives the actuator, not a record's sensor.\n"
        if model.drift is not None
        else ""
    )
    h = f"""/* Generated by `piezohyst export-c` from {source} -- do not edit.
 * Model: {model.kind} (family {fam}, dims {dims}), \
input {model.units.get("input") or "?"} -> output {model.units.get("output") or "?"}.
 * The values are exact: hex literals of the doubles piezohyst identified. */
#ifndef PIEZOHYST_MODEL_H
#define PIEZOHYST_MODEL_H

#include "piezohyst.h"

#define PIEZOHYST_MODEL_FAMILY PHS_FAMILY_{fam.upper()}
#define PIEZOHYST_MODEL_N_PARAMS {n_params}
#define PIEZOHYST_MODEL_SCRATCH_LEN {scratch}

/* The model's output map: output = GAIN * h + OFFSET, h the family's output (what
 * phs_model_step gives and phs_model_inverse_step inverts). The parameter row does not hold
 * it: use piezohyst_model_step / piezohyst_model_inverse_step, which apply it. */
#define PIEZOHYST_MODEL_OUTPUT_OFFSET {_c_double(omap.offset)} /* {omap.offset!r} */
#define PIEZOHYST_MODEL_OUTPUT_GAIN {_c_double(omap.gain)} /* {omap.gain!r} */

/* The model's input delay in samples: the family's core sees the input DELAY samples late
 * (before the first sample after a reset, the input is taken as held at its first value).
 * piezohyst_model_step runs the delay line, kept in the state after the core's slots
 * (PIEZOHYST_MODEL_STATE_LEN = CORE_STATE_LEN, + DELAY + 1 with a delay: the line, oldest
 * first, then the samples since the reset). The inverse cannot undo a delay (it would need the
 * desired output DELAY samples ahead): piezohyst_model_inverse_step inverts the undelayed
 * model on a core state (CORE_STATE_LEN slots); driven by its inputs, the delayed model
 * follows the desired output DELAY samples late.{drift_note} */
#define PIEZOHYST_MODEL_INPUT_DELAY {delay}
#define PIEZOHYST_MODEL_CORE_STATE_LEN {n_core}
#define PIEZOHYST_MODEL_STATE_LEN {n_state}

extern const double piezohyst_model_params[PIEZOHYST_MODEL_N_PARAMS];
extern const PhsModelSpec piezohyst_model_spec;

/* Initialize `model` from the exported parameters. The model borrows a static scratch
 * buffer of piezohyst_model.c: initialize it once (copies of the struct are fine). */
PhsStatus piezohyst_model_init(PhsModel *model);

/* The relaxed state of piezohyst_model_step (n_state = PIEZOHYST_MODEL_STATE_LEN). */
PhsStatus piezohyst_model_reset(const PhsModel *model, double *state, size_t n_state);

/* The model's output for input `v` (the delay line, phs_model_step, the output map): what
 * piezohyst's simulate gives, sample for sample (n_state = PIEZOHYST_MODEL_STATE_LEN). */
PhsStatus piezohyst_model_step(const PhsModel *model, double *state, size_t n_state, double v, double *y_out);

/* The undelayed model's output (phs_model_step through the output map) on a core state
 * (n_state = PIEZOHYST_MODEL_CORE_STATE_LEN): what piezohyst_model_inverse_step inverts. */
PhsStatus piezohyst_model_undelayed_step(const PhsModel *model, double *state, size_t n_state, double v,
                                         double *y_out);

/* The input that gives the output `y_desired` (the output map removed, then
 * phs_model_inverse_step) on a core state (n_state = PIEZOHYST_MODEL_CORE_STATE_LEN): what
 * piezohyst's inverse().step gives. */
PhsStatus piezohyst_model_inverse_step(const PhsModel *model, double *state, size_t n_state, double y_desired,
                                       double guess, double *v_out);

#endif /* PIEZOHYST_MODEL_H */
"""
    delay_step = (
        """    if (PIEZOHYST_MODEL_INPUT_DELAY > 0) {
        double *line, *age, late;
        size_t i;
        if (state == NULL || n_state != PIEZOHYST_MODEL_STATE_LEN)
            return phs_model_step(model, state, n_state, v, &h); /* the library's null / length error */
        line = state + PIEZOHYST_MODEL_CORE_STATE_LEN;
        age = line + PIEZOHYST_MODEL_INPUT_DELAY;
        if (!(*age >= 0.0) || *age != floor(*age)) return PHS_ERR_INVALID_PARAMETER; /* samples since the reset */
        if (*age == 0.0) /* the first sample after a reset: the input held before it */
            for (i = 0; i < (size_t)PIEZOHYST_MODEL_INPUT_DELAY; i++) line[i] = v;
        late = line[0];
        status = phs_model_step(model, state, PIEZOHYST_MODEL_CORE_STATE_LEN, late, &h);
        if (status != PHS_OK) return status;
        for (i = 0; i + 1 < (size_t)PIEZOHYST_MODEL_INPUT_DELAY; i++) line[i] = line[i + 1];
        line[PIEZOHYST_MODEL_INPUT_DELAY - 1] = v;
        *age += 1.0;
        *y_out = PIEZOHYST_MODEL_OUTPUT_GAIN * h + PIEZOHYST_MODEL_OUTPUT_OFFSET;
        return PHS_OK;
    }
"""
        if delay
        else ""
    )
    reset = (
        """    PhsStatus status = phs_model_reset(model, state, n_state < PIEZOHYST_MODEL_CORE_STATE_LEN ? n_state
                                                                                   : PIEZOHYST_MODEL_CORE_STATE_LEN);
    size_t i;
    if (status != PHS_OK) return status;
    if (n_state != PIEZOHYST_MODEL_STATE_LEN)
        return phs_model_reset(model, state, n_state); /* the library's length error */
    for (i = PIEZOHYST_MODEL_CORE_STATE_LEN; i < PIEZOHYST_MODEL_STATE_LEN; i++) state[i] = 0.0;
    return PHS_OK;
"""
        if delay
        else "    return phs_model_reset(model, state, n_state);\n"
    )
    c = f"""/* Generated by `piezohyst export-c` from {source} -- do not edit. */
#include "piezohyst_model.h"

#include <math.h> /* INFINITY, for an open input range; floor */

{_c_array("piezohyst_model_params", row, names)}

const PhsModelSpec piezohyst_model_spec = {{
    PIEZOHYST_MODEL_FAMILY, {len(dims)}, {{{", ".join(str(x) for x in dims4)}}}, \
piezohyst_model_params, PIEZOHYST_MODEL_N_PARAMS
}};

static double piezohyst_model_scratch[PIEZOHYST_MODEL_SCRATCH_LEN > 0 ? PIEZOHYST_MODEL_SCRATCH_LEN : 1];

PhsStatus piezohyst_model_init(PhsModel *model) {{
    return phs_model_init(model, &piezohyst_model_spec,
                          PIEZOHYST_MODEL_SCRATCH_LEN > 0 ? piezohyst_model_scratch : NULL,
                          PIEZOHYST_MODEL_SCRATCH_LEN);
}}

PhsStatus piezohyst_model_reset(const PhsModel *model, double *state, size_t n_state) {{
{reset}}}

PhsStatus piezohyst_model_undelayed_step(const PhsModel *model, double *state, size_t n_state, double v,
                                         double *y_out) {{
    double h;
    PhsStatus status = phs_model_step(model, state, n_state, v, &h);
    if (status == PHS_OK) *y_out = PIEZOHYST_MODEL_OUTPUT_GAIN * h + PIEZOHYST_MODEL_OUTPUT_OFFSET;
    return status;
}}

PhsStatus piezohyst_model_step(const PhsModel *model, double *state, size_t n_state, double v, double *y_out) {{
    double h;
    PhsStatus status;
{delay_step}    status = phs_model_step(model, state, n_state, v, &h);
    if (status == PHS_OK) *y_out = PIEZOHYST_MODEL_OUTPUT_GAIN * h + PIEZOHYST_MODEL_OUTPUT_OFFSET;
    return status;
}}

PhsStatus piezohyst_model_inverse_step(const PhsModel *model, double *state, size_t n_state, double y_desired,
                                       double guess, double *v_out) {{
    double h = (y_desired - PIEZOHYST_MODEL_OUTPUT_OFFSET) / PIEZOHYST_MODEL_OUTPUT_GAIN;
    return phs_model_inverse_step(model, state, n_state, h, guess, v_out);
}}
"""
    return {"piezohyst_model.h": h, "piezohyst_model.c": c}


def _controller_files(c: ExportedController, source: str) -> dict[str, str]:
    kind = c.kind
    names = CONTROLLER_PARAMS[kind]
    spec = c.core(_StageStub(c.sample_time))
    n_state = int(_core.controller_initial_state(spec, 0.0).size)
    inv = c.inverse
    ilc = c.ilc
    h = f"""/* Generated by `piezohyst export-c` from {source} -- do not edit.
 * Controller: {kind}{" behind the exact inverse of the exported model" if inv else ""}{" with ILC" if ilc else ""}.
 * {c.description.replace("*/", "* /")[:300]} */
#ifndef PIEZOHYST_CONTROLLER_H
#define PIEZOHYST_CONTROLLER_H

#include "piezohyst.h"

#define PIEZOHYST_CONTROLLER_KIND PHS_CONTROLLER_{kind.upper()}
#define PIEZOHYST_CONTROLLER_N_PARAMS {len(names)}
#define PIEZOHYST_CONTROLLER_STATE_LEN {n_state}
#define PIEZOHYST_CONTROLLER_HAS_INVERSE {1 if inv else 0}
#define PIEZOHYST_CONTROLLER_HAS_ILC {1 if ilc else 0}
#define PIEZOHYST_SAMPLE_TIME {_c_double(c.sample_time)} /* {c.sample_time!r} s */

extern const double piezohyst_controller_params[PIEZOHYST_CONTROLLER_N_PARAMS];

/* Initialize `controller` from the exported parameters. `inverse_model` is the
 * initialized exported model (piezohyst_model_init) when PIEZOHYST_CONTROLLER_HAS_INVERSE,
 * else it is not used and may be NULL. The state needs PIEZOHYST_CONTROLLER_STATE_LEN
 * doubles (also phs_controller_state_len). */
PhsStatus piezohyst_controller_init(PhsController *controller, const PhsModel *inverse_model);

#endif /* PIEZOHYST_CONTROLLER_H */
"""
    body = []
    if inv:
        body.append(
            f"    const PhsInverse inverse = {{inverse_model, {_c_double(inv[3])}, {_c_double(inv[4])}}}; "
            f"/* voltage limits {inv[3]!r} .. {inv[4]!r} */"
        )
    if ilc:
        body.append(
            f"    static const PhsIlcSpec ilc = {{{ilc[0]}, {_c_double(ilc[1])}, "
            f"{_c_double(ilc[2])}, {ilc[3]}, {ilc[4]}}}; "
            f"/* period, gain {ilc[1]!r}, forgetting {ilc[2]!r}, lead, delay */"
        )
    if not inv:
        body.append("    (void)inverse_model;")
    body.append(
        f"    return phs_controller_init(controller, PIEZOHYST_CONTROLLER_KIND, piezohyst_controller_params,\n"
        f"                               PIEZOHYST_CONTROLLER_N_PARAMS, {'&inverse' if inv else 'NULL'}, "
        f"{'&ilc' if ilc else 'NULL'});"
    )
    body_text = "\n".join(body)
    cc = f"""/* Generated by `piezohyst export-c` from {source} -- do not edit. */
#include "piezohyst_controller.h"

#include <math.h> /* INFINITY, for an open limit */
#include <stddef.h>

{_c_array("piezohyst_controller_params", c.params, names)}

PhsStatus piezohyst_controller_init(PhsController *controller, const PhsModel *inverse_model) {{
{body_text}
}}
"""
    return {"piezohyst_controller.h": h, "piezohyst_controller.c": cc}


@dataclass(frozen=True)
class _StageStub:
    sample_time: float


def demo_input_range(model: HysteresisModel) -> tuple[float, float]:
    """The input range ``example.c`` drives the model over: the model's own input range when
    it has one (a finite GPI/MPI ``input_range``, Preisach grid), else ``[0, 2 max threshold]``
    for the PI family, else ``[-1, 1]``."""
    row = model.to_row()
    fam = model.family
    groups = _groups(fam, model.dims)
    if fam in _INPUT_RANGE_GROUPS:
        lo, hi = (row[groups[g]] for g in _INPUT_RANGE_GROUPS[fam])
        if np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)):
            return float(lo[0]), float(hi[0])
    if fam in ("pi", "rdpi"):
        r = row[groups["r"]]  # the thresholds, increasing
        if r.size and r[-1] > 0:
            return 0.0, float(2 * r[-1])
    return -1.0, 1.0


#: The groups of the layout table holding a family's own input range ``(low, high)``.
_INPUT_RANGE_GROUPS = {"gpi": ("range_lo", "range_hi"), "preisach": ("lo", "hi")}


def _groups(family: str, dims: Iterable[int]) -> dict[str, slice]:
    """Where each declared group of a family's row lies (the core's layout table,
    ``_core.family_layout``): ``{name: slice}``."""
    layout = _core.family_layout(family, [int(x) for x in dims])
    return {name: slice(offset, offset + length) for name, offset, length in layout["groups"]}


#: Samples per triangle period of the example's reference (the ILC period when learning).
EXAMPLE_PERIOD = 1000


class ExamplePlan(TypedDict):
    """The constants of ``example.c``: the input range and the triangle's period and length,
    with a controller also the reference's range and the sample time."""

    v_lo: float
    v_hi: float
    period: int
    steps: int
    x_lo: NotRequired[float]
    x_hi: NotRequired[float]
    ts: NotRequired[float]


def example_plan(
    model: HysteresisModel,
    controller: ExportedController | None,
    input_range: Sequence[float] | None = None,
    steps: int | None = None,
) -> ExamplePlan:
    """The constants ``example.c`` runs with (also what the test reproduces in Python)."""
    lo, hi = demo_input_range(model) if input_range is None else (float(input_range[0]), float(input_range[1]))
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise ParameterError(f"input range [{lo}, {hi}] must be finite with low < high")
    period = EXAMPLE_PERIOD if controller is None or controller.ilc is None else int(controller.ilc[0])
    period = max(period, 4)
    n = 3 * period if steps is None else int(steps)
    if n < 1:
        raise ParameterError(f"steps = {n} must be >= 1")
    plan: ExamplePlan = {"v_lo": lo, "v_hi": hi, "period": period, "steps": n}
    if controller is not None:
        # the reference stays inside the middle 60 % of the outputs over the input range
        v = np.concatenate(
            [
                np.linspace(0.0, hi, 200) if lo < 0 < hi else np.linspace(lo, hi, 200),
                np.linspace(hi, lo, 400),
                np.linspace(lo, hi, 400),
            ]
        )
        y = model.simulate(np.clip(v, lo, hi))
        y_lo, y_hi = float(np.min(y[200:])), float(np.max(y[200:]))
        span = y_hi - y_lo
        if not span > 0:
            raise ParameterError("the model's output does not vary over the input range; give --input-range")
        plan.update({"x_lo": y_lo + 0.2 * span, "x_hi": y_hi - 0.2 * span, "ts": controller.sample_time})
    return plan


def _example_c(model: HysteresisModel, controller: ExportedController | None, plan: ExamplePlan, lib_hint: str) -> str:
    head = f"""/* Generated by `piezohyst export-c` -- a minimal real-time loop on the exported objects.
 *
 * Build (the directory holds piezohyst.h; link the static library of crates/capi):
 *     cc -std=c99 -O2 -ffp-contract=off -I. example.c \
piezohyst_model.c{" piezohyst_controller.c" if controller else ""} \\
 *        {lib_hint} {LINK_LIBS} -o example
 * Run: ./example            (summary)
 *      ./example --trace    (every sample, for checking against Python)
 *
 * No allocation: the model, the controller and their states are static; every call
 * returns a PhsStatus and phs_last_error_message() says why a call failed. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "piezohyst.h"
#include "piezohyst_model.h"
"""
    check = """
static int check(PhsStatus status, const char *what) {
    if (status != PHS_OK) {
        fprintf(stderr, "%s failed: %s (%s)\\n", what, phs_status_name(status), phs_last_error_message());
        return 1;
    }
    return 0;
}
"""
    tri = f"""
#define STEPS {plan["steps"]}
#define PERIOD {plan["period"]}

/* a triangle between lo and hi, PERIOD samples long; slope out in *rate (per sample) */
static double triangle(long k, double lo, double hi, double *rate) {{
    double phase = (double)(k % PERIOD) / (double)PERIOD;
    if (phase < 0.5) {{
        *rate = 2.0 * (hi - lo) / (double)PERIOD;
        return lo + (hi - lo) * (2.0 * phase);
    }}
    *rate = -2.0 * (hi - lo) / (double)PERIOD;
    return lo + (hi - lo) * (2.0 - 2.0 * phase);
}}
"""
    if controller is None:
        main = f"""
#define V_LO {_c_double(plan["v_lo"])} /* {plan["v_lo"]!r} */
#define V_HI {_c_double(plan["v_hi"])} /* {plan["v_hi"]!r} */

static PhsModel model;
static double forward[PIEZOHYST_MODEL_STATE_LEN > 0 ? PIEZOHYST_MODEL_STATE_LEN : 1];
static double inverse[PIEZOHYST_MODEL_CORE_STATE_LEN > 0 ? PIEZOHYST_MODEL_CORE_STATE_LEN : 1];
static double check_state[PIEZOHYST_MODEL_CORE_STATE_LEN > 0 ? PIEZOHYST_MODEL_CORE_STATE_LEN : 1];

/* Inverse feedforward: drive the model with a triangle (forward), invert its outputs
 * sample by sample (what a compensator in front of the actuator does), and check that the
 * model driven by the inverse's inputs reproduces them (the undelayed model: the inverse
 * cannot undo an input delay). */
int main(int argc, char **argv) {{
    int trace = argc > 1 && strcmp(argv[1], "--trace") == 0;
    const size_t n = PIEZOHYST_MODEL_STATE_LEN, nc = PIEZOHYST_MODEL_CORE_STATE_LEN;
    double guess = 0.0, worst = 0.0, largest = 0.0, rate;
    long k;
    if (check(piezohyst_model_init(&model), "piezohyst_model_init")) return 1;
    if (check(piezohyst_model_reset(&model, forward, n), "piezohyst_model_reset")) return 1;
    if (check(phs_model_reset(&model, inverse, nc), "phs_model_reset")) return 1;
    if (check(phs_model_reset(&model, check_state, nc), "phs_model_reset")) return 1;
    for (k = 0; k < STEPS; k++) {{
        double v = triangle(k, V_LO, V_HI, &rate), y, v_inv, y_back;
        if (check(piezohyst_model_step(&model, forward, n, v, &y), "piezohyst_model_step")) return 1;
        if (check(piezohyst_model_inverse_step(&model, inverse, nc, y, guess, &v_inv), "piezohyst_model_inverse_step"))
            return 1;
        guess = v_inv;
        if (check(piezohyst_model_undelayed_step(&model, check_state, nc, v_inv, &y_back),
                  "piezohyst_model_undelayed_step"))
            return 1;
        if (fabs(y_back - y) > worst) worst = fabs(y_back - y);
        if (fabs(y) > largest) largest = fabs(y);
        if (trace) printf("%ld %.17g %.17g %.17g\\n", k, v, y, v_inv);
    }}
    if (!trace) {{
        printf("piezohyst %s: exported model, %d samples of a triangle over [%g, %g]\\n", \
phs_version(), STEPS, V_LO, V_HI);
        printf("max |model(inverse(y)) - y| = %.3g\\n", worst);
    }}
    return worst <= 1e-9 * largest ? 0 : 1;
}}
"""
    else:
        main = f"""#include "piezohyst_controller.h"

#define X_LO {_c_double(plan["x_lo"])} /* {plan["x_lo"]!r} */
#define X_HI {_c_double(plan["x_hi"])} /* {plan["x_hi"]!r} */
#define TS PIEZOHYST_SAMPLE_TIME

static PhsModel model;
static PhsController controller;
static double plant[PIEZOHYST_MODEL_STATE_LEN > 0 ? PIEZOHYST_MODEL_STATE_LEN : 1];
static double state[PIEZOHYST_CONTROLLER_STATE_LEN > 0 ? PIEZOHYST_CONTROLLER_STATE_LEN : 1];

/* The loop of a real-time task, one iteration per sample: read the sensor, step the
 * controller, write the amplifier command. Here the "plant" is the exported hysteresis
 * model itself (no dynamics) read one sample late; on hardware, replace plant_read() and
 * plant_write() by the ADC and DAC. */
static double position;
static double plant_read(void) {{ return position; }}
static int plant_write(double u) {{
    return check(piezohyst_model_step(&model, plant, PIEZOHYST_MODEL_STATE_LEN, u, &position), "piezohyst_model_step");
}}

int main(int argc, char **argv) {{
    int trace = argc > 1 && strcmp(argv[1], "--trace") == 0;
    size_t n_state = 0;
    double sse = 0.0, rate;
    long k;
    if (check(piezohyst_model_init(&model), "piezohyst_model_init")) return 1;
    if (check(piezohyst_controller_init(&controller, &model), "piezohyst_controller_init")) return 1;
    if (check(phs_controller_state_len(&controller, &n_state), "phs_controller_state_len")) return 1;
    if (n_state != PIEZOHYST_CONTROLLER_STATE_LEN) {{
        fprintf(stderr, "state length %zu, expected %d\\n", n_state, PIEZOHYST_CONTROLLER_STATE_LEN);
        return 1;
    }}
    if (check(piezohyst_model_reset(&model, plant, PIEZOHYST_MODEL_STATE_LEN), "piezohyst_model_reset")) return 1;
    if (plant_write(0.0)) return 1;   /* the plant at rest at 0 V */
    if (check(phs_controller_reset(&controller, state, n_state, plant_read()), "phs_controller_reset")) return 1;
    for (k = 0; k < STEPS; k++) {{
        double x = triangle(k, X_LO, X_HI, &rate), y = plant_read(), u;
        if (check(phs_controller_step(&controller, state, n_state, x, \
rate / TS, 0.0, y, &u), "phs_controller_step")) return 1;
        if (plant_write(u)) return 1;
        if (k >= STEPS / 3) sse += (x - y) * (x - y);
        if (trace) printf("%ld %.17g %.17g %.17g\\n", k, x, y, u);
    }}
    if (!trace) {{
        printf("piezohyst %s: exported controller (kind %d) on the exported model, %d samples\\n", phs_version(),
               PIEZOHYST_CONTROLLER_KIND, STEPS);
        printf("reference triangle %.6g .. %.6g, RMS error after the first third %.4g\\n", X_LO, X_HI,
               sqrt(sse / (double)(STEPS - STEPS / 3)));
    }}
    return 0;
}}
"""
    return head + check + tri + main


def export_c(
    model: HysteresisModel,
    out_dir: PathLike,
    *,
    controller: ExportedController | dict[str, Any] | None = None,
    force: bool = False,
    source: str = "Python",
    input_range: Sequence[float] | None = None,
    steps: int | None = None,
    name: str = "out_dir",
) -> list[Path]:
    """Write the C initializers of ``model`` (and ``controller``, an
    :class:`ExportedController` or a controller file's dict) into ``out_dir`` with
    ``piezohyst.h`` and ``example.c``. Existing files are kept unless ``force``. The files are
    written as a set (:func:`piezohyst.outputs.output_set`): an interrupted or failed export
    leaves the folder as it was; with ``force`` a file of an earlier export that this one does
    not write (a controller's) is removed with the old set. A controller behind an inverse
    model must have been built on ``model``. Returns the written paths.

    Parameters
    ----------
    model : HysteresisModel
        The model to export (its exact inverse is the example's feedforward).
    out_dir : str or os.PathLike
        The folder to write into (created if missing).
    controller : ExportedController or dict, optional
        A controller to export with the model (:func:`load_controller`).
    force : bool
        Overwrite existing files.
    source : str
        Where the model came from, written in the generated files' header comment.
    input_range : (float, float), optional
        The input range ``example.c`` drives the model over (default: the model's own).
    steps : int, optional
        Samples ``example.c`` runs (default: three reference periods).
    name : str
        The argument error messages name (the CLI passes ``--out``).

    Returns
    -------
    list of pathlib.Path

    Examples
    --------
    >>> import tempfile
    >>> from piezohyst import PI
    >>> from piezohyst.export import export_c
    >>> files = export_c(PI([0.1, 0.3], [0.4, 0.2], p0=1.0), tempfile.mkdtemp(), source="the docs")
    >>> sorted(p.name for p in files)[:3]
    ['example.c', 'piezohyst.h', 'piezohyst_model.c']
    >>> "from the docs" in files[0].read_text()
    True
    """
    model = _as_model(model)
    controller = _as_exported(controller)
    if controller is not None and controller.inverse is not None:
        # the controller inverts a bare row: the one holding the model's output map
        model = model.mapped_row((float(controller.inverse[3]), float(controller.inverse[4])))
        fam, dims, row = controller.inverse[:3]
        if fam != model.family or tuple(dims) != tuple(model.dims) or not np.array_equal(np.array(row), model.to_row()):
            raise ParameterError(
                f"the controller acts behind the inverse of a {fam} model with dims {list(dims)} that is "
                f"not MODEL (a {model.family} model with dims {list(model.dims)}, or different parameters); "
                f"export the model the controller was built on"
            )
    out = Path(out_dir)
    files = _model_files(model, source)
    if controller is not None:
        files.update(_controller_files(controller, source))
    plan = example_plan(model, controller, input_range, steps)
    lib = library_path()
    files["example.c"] = _example_c(model, controller, plan, str(lib) if lib else "path/to/libpiezohyst.a")
    header = header_path()
    names = list(files) + (["piezohyst.h"] if header else [])
    # the folder gets the new set whole or keeps the old one (piezohyst.outputs.output_set);
    # a file of an earlier export this one does not write (a controller) goes with the old set
    with output_set(
        out,
        name=name,
        overwrite=force,
        names=names,
        previous=EXPORT_FILES,
        parents=True,
        force_hint="--force" if name.startswith("--") else "force=True",
    ) as tmp:
        for n, text in files.items():
            (tmp / n).write_text(text, encoding="utf-8")
        if header:
            shutil.copyfile(header, tmp / "piezohyst.h")
    return [out / n for n in names]


def _as_model(model: object) -> HysteresisModel:
    """``model`` if it is a hysteresis model, else ``ParameterTypeError``."""
    from ..models.model import HysteresisModel

    if not isinstance(model, HysteresisModel):
        raise ParameterTypeError(f"model must be a hysteresis model, got {type(model).__name__}")
    return model


def _as_exported(controller: object) -> ExportedController | None:
    """``controller`` as an :class:`ExportedController` (a controller file's dict is read),
    ``None`` if ``None``, else ``ParameterTypeError``."""
    if isinstance(controller, dict):
        controller = controller_from_dict(controller)
    if controller is not None and not isinstance(controller, ExportedController):
        raise ParameterTypeError(
            f"controller must be an ExportedController (load_controller) or its dict, got {type(controller).__name__}"
        )
    return controller
