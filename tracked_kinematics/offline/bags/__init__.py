"""
Reading and writing rosbags as plain arrays (rosbags, no ROS install).

The face of the sub-package: :mod:`.sources` says what to read, :mod:`.reader` reads it
(:func:`read_recording`, the one bag reader: every stream of a bag in one pass, one time-0
rule), :mod:`.writer` writes bags. Behind the reader: :mod:`.opening` (the bag and its
topics), :mod:`.streaming` (the one message loop), the decoders :mod:`.joint_states`,
:mod:`.side_streams`, :mod:`.ground_truth`, :mod:`.imu_gnss`, :mod:`.commands`, and
:mod:`.columns` (the growing arrays they fill).
"""

from tracked_kinematics.core.encoder_modes import TICK_BITS
from tracked_kinematics.offline.errors import BagError

from .reader import IMU_AUTO, read_recording, read_recordings
from .sources import (CMD_VEL_TOPIC, CMD_VEL_TYPES, COMMAND_KINDS, CommandSource, EncoderSource,
                      GROUND_TRUTH_TYPES, GroundTruthSource, SETPOINT_TOPICS)
from .writer import BagWriter, STORAGES

__all__ = [
    'BagError', 'BagWriter', 'CMD_VEL_TOPIC', 'CMD_VEL_TYPES', 'COMMAND_KINDS', 'CommandSource',
    'EncoderSource', 'GROUND_TRUTH_TYPES', 'GroundTruthSource', 'IMU_AUTO', 'SETPOINT_TOPICS',
    'STORAGES', 'TICK_BITS', 'read_recording', 'read_recordings',
]
