"""Population optimizers over a box (CSS, PSO, MPSO, DE) and :func:`minimize`, in
:mod:`.core`; this package is the former module ``piezohyst.optimize``."""

from .core import (
    CSS,
    DE,
    METHODS,
    MPSO,
    PSO,
    IntermediateResult,
    Optimizer,
    OptimizeResult,
    css_charges,
    css_forces,
    minimize,
)
from .report import RunReport

__all__ = [
    "CSS",
    "DE",
    "METHODS",
    "MPSO",
    "PSO",
    "IntermediateResult",
    "OptimizeResult",
    "Optimizer",
    "RunReport",
    "css_charges",
    "css_forces",
    "minimize",
]
