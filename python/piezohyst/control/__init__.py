"""Control: the controllers (:mod:`.controllers`), closed-loop simulation (:mod:`.simulation`),
tuning/tracking (:mod:`.tuning`) and feedforward of MIMO models (:mod:`.mimo`). This package
is the former module ``piezohyst.control`` (every public name of it is here)."""

from .controllers import (
    ABSMC,
    ILC,
    PID,
    SMC,
    CemfFeedforward,
    Compensated,
    FilteredPID,
    InverseFeedforward,
    OpenLoop,
    SampleRateWarning,
    VelocityObserver,
    cemf_model_parameters,
    check_sample_rate,
    is_controller,
    with_gains,
)
from .mimo import MimoFeedforward, frequency_response, mirror_matrix, periodic_response
from .multiaxis import MultiAxisResult, closed_loop_multi
from .simulation import ClosedLoopResult, closed_loop, closed_loop_batch
from .tuning import MultiAxisTuningResult, TuningResult, stage_from_model, track, tune, tune_axes

__all__ = [
    "ABSMC",
    "ILC",
    "PID",
    "SMC",
    "CemfFeedforward",
    "ClosedLoopResult",
    "Compensated",
    "FilteredPID",
    "InverseFeedforward",
    "MimoFeedforward",
    "MultiAxisResult",
    "MultiAxisTuningResult",
    "OpenLoop",
    "SampleRateWarning",
    "TuningResult",
    "VelocityObserver",
    "cemf_model_parameters",
    "check_sample_rate",
    "closed_loop",
    "closed_loop_batch",
    "closed_loop_multi",
    "frequency_response",
    "is_controller",
    "mirror_matrix",
    "periodic_response",
    "stage_from_model",
    "track",
    "tune",
    "tune_axes",
    "with_gains",
]
