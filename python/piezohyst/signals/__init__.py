"""Signals: measured records and their file readers (:mod:`.data`), multi-channel records
(:mod:`.multichannel`), their preprocessing (:mod:`.preprocess`), reference trajectories
(:mod:`.references`; jerk-limited moves and input shaping: :mod:`.trajectory`),
tracking/hysteresis metrics (:mod:`.metrics`), frequency responses (:mod:`.frequency`), the
best linear approximation of multisine records (:mod:`.frf`) and :class:`.Response`, the
result of every time simulation."""

from .data import Record, load_record, load_yan9a_model_record
from .frequency import FrequencyResponse, frf_from_record
from .frf import BestLinearApproximation, estimate_bla, multisine_records
from .metrics import hysteresis_percent, linearity_error, max_error, rmse, tracking_metrics
from .multichannel import MultiRecord, is_multichannel, load_multichannel, read_channels
from .preprocess import (
    apply_lag,
    decimate,
    estimate_lag,
    find_excitation_start,
    flag_outliers,
    preprocess,
    processed_index,
    remove_drift,
    replace_outliers,
)
from .references import chirp, multisine, sine, staircase, triangle, variable_amplitude_sine
from .response import Response
from .trajectory import input_shaper, jerk_limited

__all__ = [
    "BestLinearApproximation",
    "FrequencyResponse",
    "MultiRecord",
    "Record",
    "Response",
    "apply_lag",
    "chirp",
    "decimate",
    "estimate_bla",
    "estimate_lag",
    "find_excitation_start",
    "flag_outliers",
    "frf_from_record",
    "hysteresis_percent",
    "input_shaper",
    "is_multichannel",
    "jerk_limited",
    "linearity_error",
    "load_multichannel",
    "load_record",
    "load_yan9a_model_record",
    "max_error",
    "multisine",
    "multisine_records",
    "preprocess",
    "processed_index",
    "read_channels",
    "remove_drift",
    "replace_outliers",
    "rmse",
    "sine",
    "staircase",
    "tracking_metrics",
    "triangle",
    "variable_amplitude_sine",
]
