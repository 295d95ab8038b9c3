"""The plant: the simulated nanopositioning stage (:mod:`.stage`), flexure-stage design
(:mod:`.flexure`) and generic experiment helpers on a stage (:mod:`.experiment`)."""

from .experiment import excitation, measure
from .flexure import A7075_YOUNGS_MODULUS, CemfCoefficients, FlexureStage, LeafSpring
from .multiaxis import MAX_AXES, MultiAxisStage
from .stage import (
    PERTURBABLE,
    Amplifier,
    Drift,
    Sensor,
    Stage,
    StageInfo,
    StageParameters,
    StageResponse,
    perturbations,
    virtual_stage,
)

__all__ = [
    "A7075_YOUNGS_MODULUS",
    "MAX_AXES",
    "PERTURBABLE",
    "Amplifier",
    "CemfCoefficients",
    "Drift",
    "FlexureStage",
    "LeafSpring",
    "MultiAxisStage",
    "Sensor",
    "Stage",
    "StageInfo",
    "StageParameters",
    "StageResponse",
    "excitation",
    "measure",
    "perturbations",
    "virtual_stage",
]
