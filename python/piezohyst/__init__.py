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
from .errors import (ComputationError, DataError, NotInvertibleError, OutputExistsError, ParameterError,
                     ParameterTypeError, PiezohystError, UnreachableError)
from .batch import batch_rmse, batch_simulate
from .boucwen_benchmark import BoucWenBenchmark, identify_boucwen_benchmark, load_train_multisine
from .creep import Creep
from .data import Record, load_record, load_yan9a_model_record
from .differential import BoucWen, Dahl, Duhem
from .model import SCHEMA_VERSION, HysteresisModel, Inverse, load_model, model_from_dict
from .pi import PI, SEED2_TABLE1, Envelope, GeneralizedPI, GeneralizedPlay, PlayOperator, RateDependentPI, mpi_seed2
from .control import ABSMC, ILC, PID, SMC, CemfFeedforward, Compensated, InverseFeedforward, OpenLoop, VelocityObserver
from .metrics import hysteresis_percent, linearity_error, tracking_metrics
from .tuning import TuningResult, stage_from_model, track, tune
from .identify import FitResult, IdentificationResult, fit_linear, identify, identify_cemf, fit_metrics, identify_mpi, identify_pi, identify_preisach
from .varpro import identify_vp
from .flexure import A7075_YOUNGS_MODULUS, CemfCoefficients, FlexureStage, LeafSpring, seed1_stage
from .optimize import CSS, DE, MPSO, PSO, IntermediateResult, OptimizeResult, Optimizer, minimize
from .preisach import Preisach
from .references import chirp, multisine, sine, staircase, triangle, variable_amplitude_sine
from .simulation import ClosedLoopResult, closed_loop, closed_loop_batch
from .stage import Amplifier, Sensor, Stage, StageInfo, StageParameters, StageResponse, virtual_stage

__version__ = _core.__version__

__all__ = [
    "PiezohystError", "ParameterError", "NotInvertibleError", "UnreachableError", "ParameterTypeError",
    "DataError", "ComputationError", "OutputExistsError",
    "ABSMC", "ILC", "SMC", "CemfFeedforward", "Compensated", "InverseFeedforward", "VelocityObserver",
    "hysteresis_percent", "linearity_error", "tracking_metrics", "TuningResult", "stage_from_model", "track", "tune",
    "A7075_YOUNGS_MODULUS",
    "Amplifier",
    "CemfCoefficients",
    "ClosedLoopResult",
    "FitResult",
    "FlexureStage",
    "LeafSpring",
    "OpenLoop",
    "PID",
    "Sensor",
    "Stage",
    "StageInfo",
    "StageParameters",
    "StageResponse",
    "chirp",
    "closed_loop",
    "closed_loop_batch",
    "IdentificationResult",
    "fit_linear",
    "identify",
    "fit_metrics",
    "identify_boucwen_benchmark",
    "identify_cemf",
    "identify_mpi",
    "identify_pi",
    "identify_preisach",
    "identify_vp",
    "load_record",
    "load_train_multisine",
    "load_yan9a_model_record",
    "multisine",
    "seed1_stage",
    "sine",
    "staircase",
    "triangle",
    "variable_amplitude_sine",
    "virtual_stage",
    "BoucWen",
    "BoucWenBenchmark",
    "CSS",
    "DE",
    "IntermediateResult",
    "MPSO",
    "OptimizeResult",
    "Optimizer",
    "PSO",
    "Record",
    "minimize",
    "Creep",
    "Dahl",
    "Duhem",
    "Envelope",
    "GeneralizedPI",
    "GeneralizedPlay",
    "HysteresisModel",
    "Inverse",
    "PI",
    "PlayOperator",
    "Preisach",
    "RateDependentPI",
    "SCHEMA_VERSION",
    "SEED2_TABLE1",
    "batch_rmse",
    "batch_simulate",
    "load_model",
    "model_from_dict",
    "mpi_seed2",
]
