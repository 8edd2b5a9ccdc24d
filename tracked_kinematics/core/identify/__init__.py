"""
Identification: fit motion models and drive trains to logged data.

Motion models (:func:`identify`, Martinez eq. 17), the ground-truth delay, the drive train, and
calibration without ground truth (:func:`fit_from_reference`). See docs/tools/identify_icr.md and
docs/tools/identify_drivetrain.md.
"""

from .delay import (
    correct_ground_truth, DelayEstimate, estimate_delay, estimate_delay_arrays, estimate_delays,
    fixed_delay)
from .drive_data import resample
from .drivetrain_fit import DriveTrainFit, fit_drivetrain
from .excitation import (
    check_excitation, Excitation, MIN_MOVING_SEGMENTS, MIN_STRAIGHT, MIN_TURNING)
from .fitting import (
    auto_heading_weight, check_identified, fit, FitResult, METHODS, REFERENCE_RESIDUAL,
    STD_LIMITS, Uncertain, UncertainError)
from .holdout import (
    dead_reckoning, ErrorStats, HoldOut, MIN_BLOCKS, MIN_SEGMENTS, MIN_WINDOWS,
    prediction_errors)
from .problem import (
    check_heading_weight, DEFAULT_HEADING_WEIGHT, LOSSES, robust_cost, SegmentProblem)
from .procedure import DataTime, Identification, identify, ModelEvaluation
from .reference import (
    check_gyro, check_saturation, fit_from_reference, fit_recordings, heading_reference,
    QUANTITIES, ReferenceFit)
from .search_space import (
    BASELINES, baselines, bounds, build_model, COMPARE_MODELS, FIT_MODELS, fit_models,
    initial_guess, search_box, steering_efficiency_guess)
from .segments import (
    build_segments, covered_spans, gap_threshold, Segments, stretches)
from .spin import spin_in_place, SpinResult
from .tuned_diff_drive import ddc_parameters, DDC_PARAMS, TunedDiffDrive
from ..errors import ExcitationError, FitError, IdentificationError, SensorDataError
from ..recording import Recording

__all__ = [
    'BASELINES', 'COMPARE_MODELS', 'DDC_PARAMS', 'DEFAULT_HEADING_WEIGHT', 'DataTime',
    'DelayEstimate', 'DriveTrainFit', 'ErrorStats', 'Excitation', 'ExcitationError',
    'FIT_MODELS', 'FitError', 'FitResult', 'HoldOut', 'Identification', 'IdentificationError',
    'LOSSES', 'METHODS', 'MIN_BLOCKS', 'MIN_MOVING_SEGMENTS', 'MIN_SEGMENTS', 'MIN_STRAIGHT',
    'MIN_TURNING', 'MIN_WINDOWS', 'ModelEvaluation', 'QUANTITIES', 'REFERENCE_RESIDUAL',
    'Recording', 'ReferenceFit', 'SensorDataError', 'STD_LIMITS',
    'SegmentProblem', 'Segments', 'SpinResult', 'TunedDiffDrive', 'Uncertain', 'UncertainError',
    'auto_heading_weight', 'baselines', 'bounds', 'build_model', 'build_segments',
    'check_excitation', 'check_gyro', 'check_heading_weight', 'check_identified',
    'check_saturation', 'correct_ground_truth', 'covered_spans', 'ddc_parameters',
    'dead_reckoning', 'estimate_delay', 'estimate_delay_arrays', 'estimate_delays', 'fit',
    'fit_drivetrain', 'fit_from_reference', 'fit_models', 'fit_recordings', 'fixed_delay',
    'gap_threshold', 'heading_reference', 'identify', 'initial_guess', 'prediction_errors',
    'resample', 'robust_cost', 'search_box', 'spin_in_place', 'steering_efficiency_guess',
    'stretches',
]
