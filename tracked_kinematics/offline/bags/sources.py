"""
What to read from a bag: the track encoders, the ground-truth pose, the commands.

Encoders, as odometry_node takes them (its ``input_mode`` parameters, docs/parameters.md):

- ``joint_states``: sensor_msgs/JointState; the joints of each side are averaged; positions
  (rad) when the messages carry them, else velocities (rad/s, trapezoidal rule); time from
  ``header.stamp``;
- ``track_speeds``: std_msgs/Float64 per side, m/s of nominal track speed;
- ``encoder_ticks``: std_msgs/Int32 or Int64 per side, wrapping tick counters.

Headerless messages are timed by the bag's receive time. Ground truth: nav_msgs/Odometry,
geometry_msgs/PoseStamped, geometry_msgs/PoseWithCovarianceStamped (``header.stamp``) or
tf2_msgs/TFMessage (the transform parent -> child), optionally moved from a tracked body to
base_link by a fixed offset. Commands (:class:`CommandSource`): std_msgs/Float64 setpoints per
side, as cmd_vel_translator publishes them, or a geometry_msgs/Twist or TwistStamped
``cmd_vel`` turned into nominal track speeds through the ideal inverse ``v -/+ w B / 2``, as
diff_drive_controller turns it into wheel speeds.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from tracked_kinematics.core.encoder_modes import encoder_decoder, ENCODER_DECODERS
from tracked_kinematics.params import ENCODER_INPUT_DEFAULTS, JOINT_STATES_TOPIC, SIDE_TOPICS

GROUND_TRUTH_TYPES = ('nav_msgs/msg/Odometry', 'geometry_msgs/msg/PoseStamped',
                      'geometry_msgs/msg/PoseWithCovarianceStamped', 'tf2_msgs/msg/TFMessage')
"""Message types a ground-truth topic may carry."""
SETPOINT_TOPICS = ('/left_track/setpoint', '/right_track/setpoint')
"""Default left and right setpoint topics."""
CMD_VEL_TOPIC = '/cmd_vel'
"""Default body-twist command topic (a base driven as diff_drive_controller is)."""
CMD_VEL_TYPES = ('geometry_msgs/msg/Twist', 'geometry_msgs/msg/TwistStamped')
"""Message types a cmd_vel topic may carry."""
COMMAND_KINDS = ('auto', 'setpoints', 'cmd_vel', 'none')
"""Command sources: per-track setpoints, cmd_vel, whichever the bag has (auto), or none."""


@dataclass(frozen=True)
class EncoderSource:
    """
    Where and how to read the track encoders.

    Attributes
    ----------
    mode : str
        One of :data:`tracked_kinematics.params.INPUT_MODES`.
    topic : str
        JointState topic (``joint_states`` mode).
    left_joints, right_joints : tuple of str
        Joints of each side (``joint_states`` mode).
    left_topic, right_topic : str
        Per-side topics (``track_speeds`` and ``encoder_ticks`` modes).
    sprocket_radius : float
        m: joint angle (rad) x radius = nominal track travel.
    ticks_per_revolution : float
        Ticks per sprocket revolution (``encoder_ticks`` mode).

    """

    mode: str = ENCODER_INPUT_DEFAULTS['input_mode']
    topic: str = '/' + JOINT_STATES_TOPIC
    left_joints: tuple = tuple(ENCODER_INPUT_DEFAULTS['left_joints'])
    right_joints: tuple = tuple(ENCODER_INPUT_DEFAULTS['right_joints'])
    left_topic: str = '/' + SIDE_TOPICS['track_speeds'][0]
    right_topic: str = '/' + SIDE_TOPICS['track_speeds'][1]
    sprocket_radius: float = 0.1
    ticks_per_revolution: float = ENCODER_INPUT_DEFAULTS['ticks_per_revolution']

    def topics(self) -> tuple[str, ...]:
        """Topics this source reads."""
        if ENCODER_DECODERS[self.mode].per_side:
            return (self.left_topic, self.right_topic)
        return (self.topic,)

    def decoder(self):
        """Return the decoder of the mode (:mod:`tracked_kinematics.core.encoder_modes`)."""
        return encoder_decoder({'input_mode': self.mode, 'left_joints': self.left_joints,
                                'right_joints': self.right_joints,
                                'sprocket_radius': self.sprocket_radius,
                                'ticks_per_revolution': self.ticks_per_revolution})


@dataclass(frozen=True)
class GroundTruthSource:
    """
    Where to read the ground-truth pose of the vehicle.

    Attributes
    ----------
    topic : str
        Odometry, PoseStamped, PoseWithCovarianceStamped or TFMessage topic.
    parent_frame, child_frame : str
        For TFMessage: the fixed frame and the tracked frame. An empty parent accepts the
        only parent that publishes ``child_frame``.
    offset : tuple of float
        Pose ``(x, y, yaw)`` of the tracked body in base_link (m, m, rad); the ground truth
        is moved to base_link by it.

    """

    topic: str
    parent_frame: str = ''
    child_frame: str = 'base_link'
    offset: tuple = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class CommandSource:
    """
    Where to read the commands: per-track setpoints, or cmd_vel through the ideal inverse.

    Attributes
    ----------
    kind : str
        One of :data:`COMMAND_KINDS`: ``setpoints``, ``cmd_vel``, ``auto`` (the setpoints
        when the bag has both topics, else cmd_vel when it has that one), ``none``.
    setpoint_topics : pair of str
        Left and right std_msgs/Float64 setpoint topics, m/s of nominal track speed.
    cmd_vel_topic : str
        geometry_msgs/Twist or TwistStamped topic.
    track_width : float
        m: the ``B`` of the ideal inverse, needed for cmd_vel (NaN: not known).
    required : bool
        With ``auto``: a bag with neither is an error (else it has no commands). The kinds
        ``setpoints`` and ``cmd_vel`` are always required.

    """

    kind: str = 'setpoints'
    setpoint_topics: tuple = SETPOINT_TOPICS
    cmd_vel_topic: str = CMD_VEL_TOPIC
    track_width: float = math.nan
    required: bool = False

    def __post_init__(self):
        if self.kind not in COMMAND_KINDS:
            raise ValueError(f'command kind must be one of {", ".join(COMMAND_KINDS)}, got '
                             f'{self.kind!r}')
        object.__setattr__(self, 'setpoint_topics', tuple(self.setpoint_topics))
