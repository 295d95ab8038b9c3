"""Hysteresis models: the common base and model files (:mod:`.model`), the play-operator
families (:mod:`.pi`), Preisach (:mod:`.preisach`), the differential models
(:mod:`.differential`), creep (:mod:`.creep`), many parameter sets at once (:mod:`.batch`),
the Bouc–Wen benchmark system (:mod:`.boucwen_benchmark`) and MIMO stage models
(:mod:`.mimo`)."""

from .batch import batch_rmse, batch_simulate
from .boucwen_benchmark import BoucWenBenchmark
from .creep import Creep
from .differential import BoucWen, Dahl, Duhem
from .mimo import MIMO_KIND, MIMO_SCHEMA_VERSION, MimoModel, is_mimo_description, load_mimo_model, mimo_from_dict
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
    "MIMO_KIND",
    "MIMO_SCHEMA_VERSION",
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
    "MimoModel",
    "ModifiedPI",
    "OutputMap",
    "PlayOperator",
    "Preisach",
    "RateDependentPI",
    "batch_rmse",
    "batch_simulate",
    "is_mimo_description",
    "load_mimo_model",
    "load_model",
    "mimo_from_dict",
    "model_from_dict",
]
