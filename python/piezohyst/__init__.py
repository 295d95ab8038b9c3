"""piezohyst — model, identify and compensate the hysteresis of piezoelectric actuators.

The hot loops run in a Rust core (``piezohyst._core``); this package holds the models'
Python interface, batch evaluation, files and the command line.

Examples
--------
>>> import numpy as np
>>> import piezohyst as ph
>>> model = ph.mpi_seed2()
>>> v = 0.5 + 0.4 * np.sin(np.linspace(0, 4 * np.pi, 400))
>>> y = model.simulate(v)
>>> v_back = model.inverse().simulate(y)
>>> bool(np.max(np.abs(v_back - v)) < 1e-9)
True
"""

from . import _core
from .batch import batch_rmse, batch_simulate
from .boucwen_benchmark import BoucWenBenchmark, identify_boucwen_benchmark, load_train_multisine
from .control import ABSMC, ILC, PID, SMC, CemfFeedforward, Compensated, InverseFeedforward, OpenLoop, VelocityObserver
from .creep import Creep
from .data import Record, load_record, load_yan9a_model_record
from .differential import BoucWen, Dahl, Duhem
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
from .flexure import A7075_YOUNGS_MODULUS, CemfCoefficients, FlexureStage, LeafSpring, seed1_stage
from .identify import (
    FitResult,
    IdentificationResult,
    fit_linear,
    fit_metrics,
    identify,
    identify_cemf,
    identify_mpi,
    identify_pi,
    identify_preisach,
)
from .metrics import hysteresis_percent, linearity_error, tracking_metrics
from .model import SCHEMA_VERSION, HysteresisModel, Inverse, load_model, model_from_dict
from .optimize import CSS, DE, MPSO, PSO, IntermediateResult, Optimizer, OptimizeResult, minimize
from .pi import PI, SEED2_TABLE1, Envelope, GeneralizedPI, GeneralizedPlay, PlayOperator, RateDependentPI, mpi_seed2
from .preisach import Preisach
from .references import chirp, multisine, sine, staircase, triangle, variable_amplitude_sine
from .simulation import ClosedLoopResult, closed_loop, closed_loop_batch
from .stage import Amplifier, Sensor, Stage, StageInfo, StageParameters, StageResponse, virtual_stage
from .tuning import TuningResult, stage_from_model, track, tune
from .varpro import identify_vp

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
    "SEED2_TABLE1",
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
    "ParameterError",
    "ParameterTypeError",
    "PiezohystError",
    "PlayOperator",
    "Preisach",
    "RateDependentPI",
    "Record",
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
    "mpi_seed2",
    "multisine",
    "seed1_stage",
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
