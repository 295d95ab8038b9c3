"""Identification: least squares over the linear parameters and the CEMF stage model
(:mod:`.core`), variable projection for the PI family's structure (:mod:`.varpro`), the
Bouc–Wen benchmark system (:mod:`.boucwen_benchmark`) and the one entry point
:func:`identify` with its registry of model kinds (:mod:`.dispatch`) and MIMO models from
multisine records (:mod:`.mimo`). This package is the former module ``piezohyst.identify``
(every public name of it is here)."""

from .boucwen_benchmark import identify_boucwen_benchmark
from .core import (
    CEMF_PARAMETERS,
    HUBER_K,
    LOSSES,
    FitResult,
    IdentificationResult,
    default_huber_delta,
    fit_linear,
    fit_metrics,
    huber_cost,
    identify_cemf,
    identify_mpi,
    identify_pi,
    identify_preisach,
    minimize_huber,
)
from .dispatch import KINDS, STRUCTURES, identify
from .mimo import (
    MIMO_KINDS,
    MimoIdentification,
    MimoRecords,
    MimoSettings,
    fit_residues,
    identify_mimo,
    protocol_rmse,
    read_multisine_folder,
    realize,
    subspace,
)
from .varpro import identify_vp

__all__ = [
    "CEMF_PARAMETERS",
    "HUBER_K",
    "KINDS",
    "LOSSES",
    "MIMO_KINDS",
    "STRUCTURES",
    "FitResult",
    "IdentificationResult",
    "MimoIdentification",
    "MimoRecords",
    "MimoSettings",
    "default_huber_delta",
    "fit_linear",
    "fit_metrics",
    "fit_residues",
    "huber_cost",
    "identify",
    "identify_boucwen_benchmark",
    "identify_cemf",
    "identify_mimo",
    "identify_mpi",
    "identify_pi",
    "identify_preisach",
    "identify_vp",
    "minimize_huber",
    "protocol_rmse",
    "read_multisine_folder",
    "realize",
    "subspace",
]
