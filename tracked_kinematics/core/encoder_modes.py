"""
The encoder input modes: one decoder each, shared by the nodes and the bag reader.

A decoder turns its messages into per-side readings, one message at a time (nodes) or as columns
into cumulative nominal travel (bags). Adding a mode is adding a class to :data:`ENCODER_DECODERS`;
see docs/nodes/odometry_node.md#encoder-input.
"""

from __future__ import annotations

import math

import numpy as np

from .encoders import (counter_increments, travel_from_ticks, travel_from_velocities,
                       unwrap_if_wrapped)

JOINT_STATE_TYPE = 'sensor_msgs/msg/JointState'
"""Message type of the ``joint_states`` mode."""
TICK_BITS = {'std_msgs/msg/Int32': 32, 'std_msgs/msg/Int64': 64}
"""Tick counter message types (``encoder_ticks``) and the width at which they wrap."""
TICK_TYPES = {'int32': 'std_msgs/msg/Int32', 'int64': 'std_msgs/msg/Int64'}
"""The message type of each value of the ``ticks_type`` parameter."""


class JointStatesDecoder:
    """sensor_msgs/JointState: the joints of each side averaged, positions else velocities."""

    mode = 'joint_states'
    topics = ('joint_states',)
    message_types = (JOINT_STATE_TYPE,)
    summary = 'sensor_msgs/JointState'
    per_side = False
    bits = 64

    def __init__(self, left_joints, right_joints, sprocket_radius: float):
        self.joints = (list(left_joints), list(right_joints))
        self.factor = sprocket_radius

    @classmethod
    def from_values(cls, values):
        """Build from parameter values (``left_joints``, ``right_joints``, ``sprocket_radius``)."""
        return cls(values['left_joints'], values['right_joints'], values['sprocket_radius'])

    def describe(self) -> str:
        """Return what the start-up log says of the joints."""
        return f' (left {self.joints[0]}, right {self.joints[1]})'

    def index(self, names):
        """Return the indices of the left and right joints in ``names``; None if one is missing."""
        where = {name: i for i, name in enumerate(names)}
        try:
            return tuple([where[j] for j in side] for side in self.joints)
        except KeyError:
            return None

    def missing(self, names) -> list:
        """Return the joints of either side that ``names`` lacks."""
        names = set(names)
        return [j for side in self.joints for j in side if j not in names]

    def reading(self, index, count: int, positions, velocities):
        """Return ``(kind, left, right)`` of a message: positions if finite, else velocities."""
        left_index, right_index = index   # the sums written out: a node's hot path
        if len(positions) == count:
            left = sum([positions[i] for i in left_index]) / len(left_index)
            right = sum([positions[i] for i in right_index]) / len(right_index)
            if math.isfinite(left) and math.isfinite(right):
                return 'position', left, right
            if len(velocities) != count:
                return 'position', left, right
        if len(velocities) == count:
            return ('velocity', sum([velocities[i] for i in left_index]) / len(left_index),
                    sum([velocities[i] for i in right_index]) / len(right_index))
        return None

    def row(self, index, count: int, positions, velocities) -> list:
        """Return ``[pos_l, pos_r, vel_l, vel_r]`` of one message (NaN where it has none)."""
        row = [math.nan] * 4
        for values, first in ((positions, 0), (velocities, 2)):
            if len(values) == count:
                row[first] = sum(float(values[i]) for i in index[0]) / len(index[0])
                row[first + 1] = sum(float(values[i]) for i in index[1]) / len(index[1])
        return row

    @staticmethod
    def side_means(values, index):
        """Return the left and right means of ``values`` (shape (N, joints)), shape (N,) each."""
        return values[:, index[0]].mean(axis=1), values[:, index[1]].mean(axis=1)

    def travel(self, t, pos_l, pos_r, vel_l, vel_r):
        """
        Return times (ns) and each side's cumulative nominal travel in m, or None.

        Positions (unwrapped) when at least half the samples have them, else velocities.
        """
        radius = self.factor
        positions = np.isfinite(pos_l) & np.isfinite(pos_r)
        if np.count_nonzero(positions) >= 2 and np.count_nonzero(positions) >= 0.5 * len(t):
            t = t[positions]
            return (t, unwrap_if_wrapped(pos_l[positions]) * radius,
                    unwrap_if_wrapped(pos_r[positions]) * radius)
        ok = np.isfinite(vel_l) & np.isfinite(vel_r)
        t, vel_l, vel_r = t[ok], vel_l[ok], vel_r[ok]
        if len(t) < 2:
            return None
        seconds = t * 1e-9
        return t, *(np.concatenate([[0.0], np.cumsum(travel_from_velocities(v, seconds, radius))])
                    for v in (vel_l, vel_r))

    def speeds(self, t, vel_l, vel_r):
        """Return times and nominal track speeds, m/s, from the joint velocities; or None."""
        ok = np.isfinite(vel_l) & np.isfinite(vel_r)
        if np.count_nonzero(ok) < 2 or np.count_nonzero(ok) < 0.5 * len(t):
            return None
        return t[ok], vel_l[ok] * self.factor, vel_r[ok] * self.factor


class TrackSpeedsDecoder:
    """std_msgs/Float64 per side: nominal track speed, m/s (trapezoidal rule)."""

    mode = 'track_speeds'
    topics = ('left_track/speed', 'right_track/speed')
    message_types = ('std_msgs/msg/Float64',)
    summary = 'std_msgs/Float64 per side, m/s'
    per_side = True
    kind = 'velocity'
    counter = False
    factor = 1.0
    bits = 64

    @classmethod
    def from_values(cls, values):
        """Build from parameter values (none needed)."""
        return cls()

    def describe(self) -> str:
        """Return what the start-up log says of the readings (nothing)."""
        return ''

    @staticmethod
    def value(msg):
        """Return the reading of one message."""
        return msg.data

    def travel(self, t, values, message_type):
        """Return the cumulative nominal travel, m, of one side's sorted samples (``t`` in ns)."""
        return np.concatenate([[0.0], np.cumsum(travel_from_velocities(values, t * 1e-9))])


class EncoderTicksDecoder:
    """std_msgs/Int32 or Int64 per side: a wrapping tick counter (``ticks_type`` None: either)."""

    mode = 'encoder_ticks'
    topics = ('left_track/ticks', 'right_track/ticks')
    summary = 'std_msgs/Int32|Int64 per side'
    per_side = True
    kind = 'ticks'
    counter = True

    def __init__(self, sprocket_radius: float, ticks_per_revolution: float,
                 ticks_type: str | None = None):
        self.radius = sprocket_radius
        self.ticks_per_revolution = ticks_per_revolution
        self.factor = 2.0 * math.pi * sprocket_radius / ticks_per_revolution
        self.message_types = (TICK_TYPES[ticks_type],) if ticks_type else tuple(TICK_BITS)
        self.bits = TICK_BITS[self.message_types[0]]

    @classmethod
    def from_values(cls, values):
        """Build from parameter values (``sprocket_radius``, ``ticks_per_revolution``, ...)."""
        return cls(values['sprocket_radius'], values['ticks_per_revolution'],
                   values.get('ticks_type'))

    def describe(self) -> str:
        """Return what the start-up log says of the ticks."""
        return f' ({1.0 / self.factor:.6g} ticks per metre)'

    @staticmethod
    def value(msg):
        """Return the reading of one message."""
        return msg.data

    def travel(self, t, values, message_type):
        """Return the cumulative nominal travel, m, of one side's sorted counter values."""
        return np.concatenate([[0.0], np.cumsum(travel_from_ticks(
            counter_increments(values.astype(np.int64), TICK_BITS[message_type]),
            self.ticks_per_revolution, self.radius))])


ENCODER_DECODERS = {cls.mode: cls for cls in (JointStatesDecoder, TrackSpeedsDecoder,
                                              EncoderTicksDecoder)}
"""The decoder class of each encoder input mode."""


def encoder_decoder(values):
    """Return the decoder of ``values['input_mode']``, built from the other (checked) values."""
    return ENCODER_DECODERS[values['input_mode']].from_values(values)
