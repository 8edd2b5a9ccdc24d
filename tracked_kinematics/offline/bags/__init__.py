"""
Reading and writing rosbags as plain arrays (rosbags, no ROS install).

The face of the sub-package: :mod:`.sources` says what to read, :mod:`.reader` reads it,
:mod:`.reference_reader` reads a gyro, GNSS or pose reference instead of ground truth,
:mod:`.writer` writes bags. Behind the readers: :mod:`.opening` (the bag and its topics),
:mod:`.streaming` (the one message loop), the decoders :mod:`.joint_states`,
:mod:`.side_streams`, :mod:`.ground_truth`, :mod:`.commands`, and :mod:`.columns` (the
growing arrays they fill).
"""

from tracked_kinematics.core.encoder_modes import TICK_BITS
from tracked_kinematics.offline.errors import BagError

from .reader import read_bag, read_bags, read_drive_bag, read_evaluation_bag
from .sources import (CMD_VEL_TOPIC, CMD_VEL_TYPES, COMMAND_KINDS, CommandSource, EncoderSource,
                      GROUND_TRUTH_TYPES, GroundTruthSource, SETPOINT_TOPICS)
from .writer import BagWriter, STORAGES

__all__ = [
    'BagError', 'BagWriter', 'CMD_VEL_TOPIC', 'CMD_VEL_TYPES', 'COMMAND_KINDS', 'CommandSource',
    'EncoderSource', 'GROUND_TRUTH_TYPES', 'GroundTruthSource', 'SETPOINT_TOPICS', 'STORAGES',
    'TICK_BITS', 'read_bag', 'read_bags', 'read_drive_bag', 'read_evaluation_bag',
]
