"""piezohyst — model, identify and compensate the hysteresis of piezoelectric actuators.

The hot loops run in a Rust core (``piezohyst._core``); this package holds the models'
Python interface, batch evaluation, files and the command line, in sub-packages by role:

- ``models``: the hysteresis models, model files, batch evaluation, the Bouc–Wen benchmark system;
- ``signals``: measured records and their readers, reference trajectories, metrics;
- ``optimize``: population optimizers;
- ``identify``: identification (least squares, variable projection, the ``identify`` dispatcher);
- ``plant``: the simulated stage, flexure design, generic experiment helpers;
- ``control``: controllers, closed-loop simulation, tuning;
- ``export``: C code export;
- ``capi``: the C library shipped in the wheel (``libpiezohyst``, ``piezohyst.h``) and the flags
  to build against it (``python -m piezohyst.capi --cflags --libs``);
- ``papers``: the seed papers' experiments, the demo and report, the benchmark suite, the
  Bouc–Wen benchmark workflow and the provenance presets (``mpi_seed2``, ``seed1_stage``);
- ``cli``: the command line, one module per command.

Shared helpers stay at the top: ``errors`` (the exception hierarchy), ``_validate``
(argument checks), ``_io`` (JSON files in), ``outputs`` (the output policy every writer
follows: regular files only, never an input, atomic files and sets), ``progress`` (progress
bars and lines on stderr) and ``_core`` (the Rust core). The
library (every sub-package but ``papers`` and ``cli``) never imports ``papers`` or ``cli``;
``tests/test_architecture.py`` holds the rules.

The former flat module paths (``piezohyst.pi``, ``piezohyst.stage``, ``piezohyst.experiments``,
...) stay importable: ``_MOVED`` below maps each to its new home, and a meta-path finder
makes the old name an alias of the same module object.

Examples
--------
>>> import numpy as np
>>> import piezohyst as ph
>>> from piezohyst.papers import mpi_seed2
>>> model = mpi_seed2()
>>> v = 0.5 + 0.4 * np.sin(np.linspace(0, 4 * np.pi, 400))
>>> y = model.simulate(v)
>>> v_back = model.inverse().simulate(y)
>>> bool(np.max(np.abs(v_back - v)) < 1e-9)
True
"""

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings
from collections.abc import Sequence
from types import ModuleType

from . import _core
from .control import (
    ABSMC,
    ILC,
    PID,
    SMC,
    CemfFeedforward,
    ClosedLoopResult,
    Compensated,
    FilteredPID,
    InverseFeedforward,
    OpenLoop,
    TuningResult,
    VelocityObserver,
    closed_loop,
    closed_loop_batch,
    stage_from_model,
    track,
    tune,
)
from .errors import (
    ComputationError,
    DataError,
    NotInvertibleError,
    OutputExistsError,
    ParameterError,
    ParameterTypeError,
    PiezohystError,
    UnreachableError,
)
from .identify import (
    FitResult,
    IdentificationResult,
    fit_linear,
    fit_metrics,
    identify,
    identify_boucwen_benchmark,
    identify_cemf,
    identify_mpi,
    identify_pi,
    identify_preisach,
    identify_vp,
)
from .models import (
    PI,
    SCHEMA_VERSION,
    BoucWen,
    BoucWenBenchmark,
    Creep,
    Dahl,
    Duhem,
    Envelope,
    GeneralizedPI,
    GeneralizedPlay,
    HysteresisModel,
    Inverse,
    OutputMap,
    PlayOperator,
    Preisach,
    RateDependentPI,
    batch_rmse,
    batch_simulate,
    load_model,
    model_from_dict,
)
from .optimize import CSS, DE, MPSO, PSO, IntermediateResult, Optimizer, OptimizeResult, RunReport, minimize
from .plant import (
    A7075_YOUNGS_MODULUS,
    Amplifier,
    CemfCoefficients,
    FlexureStage,
    LeafSpring,
    Sensor,
    Stage,
    StageInfo,
    StageParameters,
    StageResponse,
    virtual_stage,
)
from .signals import (
    Record,
    Response,
    chirp,
    hysteresis_percent,
    linearity_error,
    load_record,
    load_yan9a_model_record,
    multisine,
    sine,
    staircase,
    tracking_metrics,
    triangle,
    variable_amplitude_sine,
)

__version__ = _core.__version__

__all__ = [
    "A7075_YOUNGS_MODULUS",
    "ABSMC",
    "CSS",
    "DE",
    "ILC",
    "MPSO",
    "PI",
    "PID",
    "PSO",
    "SCHEMA_VERSION",
    "SMC",
    "Amplifier",
    "BoucWen",
    "BoucWenBenchmark",
    "CemfCoefficients",
    "CemfFeedforward",
    "ClosedLoopResult",
    "Compensated",
    "ComputationError",
    "Creep",
    "Dahl",
    "DataError",
    "Duhem",
    "Envelope",
    "FilteredPID",
    "FitResult",
    "FlexureStage",
    "GeneralizedPI",
    "GeneralizedPlay",
    "HysteresisModel",
    "IdentificationResult",
    "IntermediateResult",
    "Inverse",
    "InverseFeedforward",
    "LeafSpring",
    "NotInvertibleError",
    "OpenLoop",
    "OptimizeResult",
    "Optimizer",
    "OutputExistsError",
    "OutputMap",
    "ParameterError",
    "ParameterTypeError",
    "PiezohystError",
    "PlayOperator",
    "Preisach",
    "RateDependentPI",
    "Record",
    "Response",
    "RunReport",
    "Sensor",
    "Stage",
    "StageInfo",
    "StageParameters",
    "StageResponse",
    "TuningResult",
    "UnreachableError",
    "VelocityObserver",
    "batch_rmse",
    "batch_simulate",
    "chirp",
    "closed_loop",
    "closed_loop_batch",
    "fit_linear",
    "fit_metrics",
    "hysteresis_percent",
    "identify",
    "identify_boucwen_benchmark",
    "identify_cemf",
    "identify_mpi",
    "identify_pi",
    "identify_preisach",
    "identify_vp",
    "linearity_error",
    "load_model",
    "load_record",
    "load_train_multisine",
    "load_yan9a_model_record",
    "minimize",
    "model_from_dict",
    "multisine",
    "sine",
    "stage_from_model",
    "staircase",
    "track",
    "tracking_metrics",
    "triangle",
    "tune",
    "variable_amplitude_sine",
    "virtual_stage",
]

#: The former flat modules and their homes: ``piezohyst.<old>`` is the module
#: ``piezohyst.<new>`` (the same object). ``identify``, ``optimize``, ``control`` and ``cli``
#: kept their names as packages that re-export the former module's public names.
_MOVED = {
    "batch": "models.batch",
    "benchmarks": "papers.benchmarks",
    "boucwen_benchmark": "papers.boucwen_benchmark",
    "creep": "models.creep",
    "data": "signals.data",
    "demo": "papers.demo",
    "differential": "models.differential",
    "experiments": "papers.experiments",
    "export_c": "export.c",
    "flexure": "plant.flexure",
    "metrics": "signals.metrics",
    "model": "models.model",
    "pi": "models.pi",
    "preisach": "models.preisach",
    "references": "signals.references",
    "report": "papers.report",
    "simulation": "control.simulation",
    "stage": "plant.stage",
    "tuning": "control.tuning",
    "varpro": "identify.varpro",
}

#: Provenance names that left ``__all__``: still importable from here, with a
#: ``DeprecationWarning`` naming their home.
_DEPRECATED = {
    "SEED2_TABLE1": "piezohyst.papers",
    "mpi_seed2": "piezohyst.papers",
    "seed1_stage": "piezohyst.papers",
}


#: Public names whose home is ``papers`` (an application wing the library never imports):
#: loaded on first use, so ``import piezohyst`` does not import ``papers``.
_FROM_PAPERS = {
    "load_train_multisine": "piezohyst.papers.boucwen_benchmark",
}


#: The application wings, imported on first attribute access (``piezohyst.papers``).
_LAZY_WINGS = ("papers", "cli")


class _MovedModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports ``piezohyst.<old>`` of ``_MOVED`` as the module at its new path."""

    _prefix = __name__ + "."

    def find_spec(
        self, fullname: str, path: Sequence[str] | None = None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname.startswith(self._prefix) and fullname[len(self._prefix) :] in _MOVED:
            return importlib.util.spec_from_loader(fullname, self)
        return None

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        module = importlib.import_module(f"{__name__}.{_MOVED[spec.name[len(self._prefix) :]]}")
        spec.loader_state = module.__spec__  # the import system sets module.__spec__ to the alias's
        return module

    def exec_module(self, module: ModuleType) -> None:
        spec = module.__spec__
        if spec is not None and spec.loader_state:
            module.__spec__ = spec.loader_state


if not any(isinstance(f, _MovedModules) for f in sys.meta_path):
    sys.meta_path.append(_MovedModules())


def __getattr__(name: str) -> object:
    if name in _DEPRECATED:
        home = _DEPRECATED[name]
        warnings.warn(
            f"piezohyst.{name} moved to {home}.{name}; import it from {home}",
            DeprecationWarning,
            stacklevel=2,
        )
        return getattr(importlib.import_module(home), name)
    if name in _FROM_PAPERS:
        return getattr(importlib.import_module(_FROM_PAPERS[name]), name)
    if name in _LAZY_WINGS:
        return importlib.import_module(f"{__name__}.{name}")
    if name in _MOVED:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
