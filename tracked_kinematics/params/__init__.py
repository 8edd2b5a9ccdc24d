"""
The parameter ring: one table of every parameter, shared by nodes, command lines and YAML.

Imports only ``core/``; docs/parameters.md is generated from :mod:`.tables`.
"""

from .files import flatten, nest, params_text, read_params_file, write_params_file
from .spec import (check_values, Derived, described_as, each, finite, frame_id, in_range,
                   missing_message, node_name, non_negative, one_of, ParamSpec, positive,
                   resolve, ros_name, typos, unknown_parameters, zero_or_at_least)
from .tables import (COMMAND_LIMIT_PARAMS, DRIVETRAIN_DEFAULTS, DRIVETRAIN_PARAMS,
                     ENCODER_INPUT_DEFAULTS, ENCODER_INPUT_PARAMS, GYRO_NOISE_PARAMS,
                     GYRO_PARAMS, INPUT_MODES, JOINT_STATES_TOPIC, LIMIT_FIELDS, limit_value,
                     NOISE_PARAMS, SIDE_TOPICS, TERRAIN_DEFAULTS, TERRAIN_PARAMS, TICKS_TYPES,
                     unknown_terrain_parameters)
from .values import (drivetrain_from_values, gyro_config_from_values,
                     gyro_noise_model_from_values, icr_from_values, limits_from_values,
                     noise_model_from_values, track_noise_from_values, values_from_drivetrain,
                     values_from_icr)

__all__ = [
    'COMMAND_LIMIT_PARAMS', 'DRIVETRAIN_DEFAULTS', 'DRIVETRAIN_PARAMS', 'Derived',
    'ENCODER_INPUT_DEFAULTS', 'ENCODER_INPUT_PARAMS', 'GYRO_NOISE_PARAMS', 'GYRO_PARAMS',
    'INPUT_MODES', 'JOINT_STATES_TOPIC', 'LIMIT_FIELDS', 'NOISE_PARAMS', 'ParamSpec',
    'SIDE_TOPICS', 'TERRAIN_DEFAULTS', 'TERRAIN_PARAMS', 'TICKS_TYPES', 'check_values',
    'described_as', 'drivetrain_from_values', 'each', 'finite', 'flatten', 'frame_id',
    'gyro_config_from_values', 'gyro_noise_model_from_values', 'icr_from_values', 'in_range',
    'limit_value', 'limits_from_values', 'missing_message', 'nest', 'node_name',
    'noise_model_from_values', 'non_negative', 'one_of', 'params_text', 'positive',
    'read_params_file', 'resolve', 'ros_name', 'track_noise_from_values', 'typos',
    'unknown_parameters',
    'unknown_terrain_parameters', 'values_from_drivetrain', 'values_from_icr', 'write_params_file',
    'zero_or_at_least',
]
