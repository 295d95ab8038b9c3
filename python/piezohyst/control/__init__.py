"""Control: the controllers (:mod:`.controllers`), closed-loop simulation (:mod:`.simulation`)
and tuning/tracking (:mod:`.tuning`). This package is the former module
``piezohyst.control`` (every public name of it is here)."""

from .controllers import (
    ABSMC,
    ILC,
    PID,
    SMC,
    CemfFeedforward,
    Compensated,
    InverseFeedforward,
    OpenLoop,
    VelocityObserver,
    cemf_model_parameters,
    is_controller,
    with_gains,
)
from .mimo import MimoFeedforward, mirror_matrix
from .simulation import ClosedLoopResult, closed_loop, closed_loop_batch
from .tuning import TuningResult, stage_from_model, track, tune

__all__ = [
    "ABSMC",
    "ILC",
    "PID",
    "SMC",
    "CemfFeedforward",
    "ClosedLoopResult",
    "Compensated",
    "InverseFeedforward",
    "MimoFeedforward",
    "OpenLoop",
    "TuningResult",
    "VelocityObserver",
    "cemf_model_parameters",
    "closed_loop",
    "closed_loop_batch",
    "is_controller",
    "mirror_matrix",
    "stage_from_model",
    "track",
    "tune",
    "with_gains",
]
