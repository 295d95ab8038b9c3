"""Hysteresis models: the common base and model files (:mod:`.model`), the play-operator
families (:mod:`.pi`), Preisach (:mod:`.preisach`), the differential models
(:mod:`.differential`), creep (:mod:`.creep`), many parameter sets at once (:mod:`.batch`)
and the Bouc–Wen benchmark system (:mod:`.boucwen_benchmark`)."""

from .batch import batch_rmse, batch_simulate
from .boucwen_benchmark import BoucWenBenchmark
from .creep import Creep
from .differential import BoucWen, Dahl, Duhem
from .model import SCHEMA_VERSION, HysteresisModel, Inverse, OutputMap, load_model, model_from_dict
from .pi import (
    PI,
    Envelope,
    EnvelopeInverse,
    GeneralizedPI,
    GeneralizedPlay,
    ModifiedPI,
    PlayOperator,
    RateDependentPI,
)
from .preisach import Preisach

__all__ = [
    "PI",
    "SCHEMA_VERSION",
    "BoucWen",
    "BoucWenBenchmark",
    "Creep",
    "Dahl",
    "Duhem",
    "Envelope",
    "EnvelopeInverse",
    "GeneralizedPI",
    "GeneralizedPlay",
    "HysteresisModel",
    "Inverse",
    "ModifiedPI",
    "OutputMap",
    "PlayOperator",
    "Preisach",
    "RateDependentPI",
    "batch_rmse",
    "batch_simulate",
    "load_model",
    "model_from_dict",
]
