"""
odometry_node's IMU intake: frames, plausible stamps, and a watchdog that says why no gyro.

Each sensor_msgs/Imu becomes ``(t, heading rate)`` for the odometry
(:func:`~tracked_kinematics.core.imu_frame.heading_rate`: the mount rotation
``imu_mount.*``, or the message's ``frame_id`` through TF where tf2_ros is importable, and
the orientation when the message has one). A sample stamped far from the encoders' time (another
clock, a stamp in 2038) is dropped with a throttled warning, so that nothing is buffered
against a time the encoders never reach and one wild stamp does not shut the gyro out. When
no sample has been usable for :data:`GRACE` s, the node's health is ``WARN`` with the reason:
no publisher, a publisher of another type, no message, stamps on another clock, every
sample refused. See docs/nodes/odometry_node.md, "IMU frames", and docs/diagnostics.md.
"""

from __future__ import annotations

from collections import Counter, deque
from collections.abc import Mapping
import math
from time import monotonic_ns
from typing import Any

from tracked_kinematics.core.gyro.samples import ORDER
from tracked_kinematics.core.imu_frame import heading_rate, mount_rotation
from tracked_kinematics.ros.health import WARN
from tracked_kinematics.ros.imu_reader import ImuReader, ImuSample
from tracked_kinematics.ros.input_topic import WARN_PERIOD

#: s without a usable sample (after start, or since the last one) before the WARN.
GRACE = 3.0

#: s a sample may be stamped ahead of (or behind) the encoders' latest stamp, after
#: ``imu_delay``: further, it is on another clock (or wild) and dropped. Another clock is off
#: by far more (a simulation's time against the wall's: years); a burst of samples taken
#: ahead of the encoders' queue (an executor busy, a bag played fast) is off by seconds and
#: must not be lost. It bounds what the odometry buffers while the encoders are silent
#: (the core keeps at most 4096 samples whatever the window).
CLOCK_WINDOW = 10.0

#: s of steady time without an encoder step after which the encoders are silent.
ENCODERS_SILENT = 1.0

#: Samples held for the next encoder step (before the first, or while the encoders are
#: silent): 2 s at 1 kHz.
HELD = 2000

_NS = 1_000_000_000
_IMU_TYPE = 'sensor_msgs/msg/Imu'


def _mount(values: Mapping[str, Any]):
    return tuple(map(tuple, mount_rotation(values['imu_mount.roll'], values['imu_mount.pitch'],
                                           values['imu_mount.yaw']).tolist()))


def _rotation_rows(q) -> tuple:
    """Rows of the rotation matrix of a unit quaternion ``(x, y, z, w)``."""
    x, y, z, w = q
    return ((1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
            (2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
            (2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)))


class ImuInput:
    """
    Turn serialised Imu messages into ``(t, heading rate)`` samples; watch that some are usable.

    Parameters
    ----------
    node : rclpy.node.Node
        The odometry node (its logger, clock, graph and ``base_frame``).
    values : mapping
        The node's parameters (``imu_mount.*``, ``imu_delay``, ``base_frame``).

    Attributes
    ----------
    reader : ImuReader
        The message reader (its ``origin`` is the node's gyro time origin).
    topic : InputTopic or None
        The subscription, for the watchdog's counts (set by the node).
    encoder_ns : int or None
        Stamp of the latest encoder step, ns (set by the node at each step).
    counts : collections.Counter
        Samples by fate: ``used``, ``refused`` (by the odometry), ``order`` (dropped by it
        as out of order), ``clock``, ``unreadable``, ``waiting`` (held for an encoder step and
        dropped, or no transform yet).

    """

    def __init__(self, node, values: Mapping[str, Any]):
        self._node = node
        self._logger = node.get_logger()
        self.reader = ImuReader()
        self.topic = None
        self.encoder_ns: int | None = None
        self._encoder_steady_ns: int | None = None
        self.counts: Counter = Counter()
        self._held: deque = deque(maxlen=HELD)
        self._start_ns = monotonic_ns()
        self._usable_ns: int | None = None
        self._why = ''               # why the latest sample was not usable
        self._warned_ns: int | None = None
        self._tf = None               # tf2_ros Buffer, once needed and importable
        self._tf_mounts: dict = {}    # frame_id -> mount rows from TF
        self._tf_warned = False
        self.orientation_used = False
        self.configure(values)

    def configure(self, values: Mapping[str, Any]) -> None:
        """Take (new) parameter values into use."""
        self._mount = _mount(values)
        self._mount_given = any(values[f'imu_mount.{axis}'] != 0.0
                                for axis in ('roll', 'pitch', 'yaw'))
        self._delay_ns = round(values['imu_delay'] * 1e9)
        self._base_frame = values['base_frame']
        self._tf_mounts = {}

    def encoder_step(self, stamp_ns: int) -> list:
        """
        Note an encoder step's stamp (ns): the time samples are checked against.

        Returns the held samples (before the first step, or while the encoders were silent)
        within :data:`CLOCK_WINDOW` of it, in order, for the odometry; the others are dropped.
        """
        self.encoder_ns = stamp_ns
        self._encoder_steady_ns = monotonic_ns()
        if not self._held:
            return []
        window = CLOCK_WINDOW * _NS
        ready = [(t, rate) for stamp, t, rate in self._held
                 if abs(stamp - self._delay_ns - stamp_ns) <= window]
        self.counts['waiting'] += len(self._held) - len(ready)
        self._held.clear()
        return ready

    # The samples ------------------------------------------------------------------------

    def take(self, data: bytes):
        """
        Return ``(t, heading rate)`` of a serialised Imu, or None when it is not to be used now.

        ``t`` in s from ``reader.origin``, rad/s. None for bytes that are not an Imu, one
        without an angular velocity (``angular_velocity_covariance[0]`` -1), a zero
        or negative stamp (or one with ``nanosec`` >= 1e9), a stamp beyond
        :data:`CLOCK_WINDOW` of the encoders' time and no mount yet (TF):
        each counted, the clock's throttled in the log. Before the first encoder step, and
        ahead of silent encoders, a sample is held (the last :data:`HELD` of them) for
        :meth:`encoder_step`.
        """
        sample = self.reader.read_sample(data)
        if sample is None:
            return self._skip('unreadable', 'a message that is no sensor_msgs/Imu', True)
        if not sample.has_rate:
            return self._skip('unreadable', 'samples without an angular velocity (their '
                              'angular_velocity_covariance[0] is -1: an orientation-only '
                              'IMU?)', True)
        if not sample.nanosec_valid:
            return self._skip('clock', 'samples whose stamp has nanosec >= 1e9 (no valid '
                              'time: a driver bug)', True)
        fate = self._stamp_fate(sample.stamp_ns)
        if fate is None:
            return None
        mount = self._mount_of(sample)
        if mount is None:
            return None
        rate, used = heading_rate(sample.omega, mount, sample.quaternion,
                                  sample.has_orientation)
        self.orientation_used = used
        t = self.reader.seconds(sample.stamp_ns)
        if fate == 'hold':
            if len(self._held) == self._held.maxlen:
                self.counts['waiting'] += 1
            self._held.append((sample.stamp_ns, t, rate))
            return None
        return t, rate

    def taken(self, accepted: bool, reason: str, dropped: int = 0) -> None:
        """
        Note whether the odometry took the sample ``take`` returned (its reason if not).

        ``dropped``: samples the odometry dropped as out of order (this one, or a wild one
        held before it), counted and warned of (throttled).
        """
        if dropped:
            self.counts['order'] += dropped
            self._logger.warning(f'{self._topic_name()}: {ORDER}: sample dropped',
                                 throttle_duration_sec=WARN_PERIOD)
        if accepted:
            self.counts['used'] += 1
            self._usable_ns = monotonic_ns()
            self._why = ''
        else:
            if not dropped:
                self.counts['refused'] += 1
            self._why = f'every sample refused by the odometry ({ORDER if dropped else reason})'

    def _skip(self, kind: str, why: str, warn: bool = False):
        if kind:
            self.counts[kind] += 1
        self._why = why
        if warn:
            self._logger.warning(f'{self._topic_name()}: {why}: sample skipped',
                                 throttle_duration_sec=WARN_PERIOD)
        return None

    def _stamp_fate(self, stamp_ns: int) -> str | None:
        """Return 'use', 'hold' (for the next encoder step) or None (dropped, counted)."""
        if stamp_ns <= 0:
            return self._skip('clock', 'samples with a zero or negative stamp (the driver '
                              'must stamp them)', True)
        if self.encoder_ns is None:
            now_ns = self._node.get_clock().now().nanoseconds
            if abs(stamp_ns - now_ns) > CLOCK_WINDOW * _NS:
                self._skip('', f'no encoder step yet, and samples stamped '
                           f"{(stamp_ns - now_ns) / _NS:+.6g} s from this node's clock")
            else:
                self._skip('', 'no encoder step yet (samples are used against the '
                           "encoders' time)")
            return 'hold'
        offset = stamp_ns - self._delay_ns - self.encoder_ns
        if abs(offset) <= CLOCK_WINDOW * _NS:
            return 'use'
        if self._encoders_silent() and offset > 0:
            self._skip('', 'the encoders are silent (samples are used against the '
                       "encoders' time)")
            return 'hold'
        return self._skip('clock', f"stamped {offset / _NS:+.6g} s from the encoders' time "
                          f'(beyond {CLOCK_WINDOW:g} s after imu_delay): another clock '
                          '(use_sim_time?), or a wild stamp', True)

    def _encoders_silent(self) -> bool:
        last = self._encoder_steady_ns
        return last is None or monotonic_ns() - last > ENCODERS_SILENT * _NS

    # Frames -----------------------------------------------------------------------------

    def _mount_of(self, sample: ImuSample):
        """Return the mount rows for a sample: imu_mount.* or TF's; None while TF has none."""
        # A ROS 1 style '/imu_link': tf2 refuses frame ids with a leading slash.
        frame = sample.frame_id.lstrip('/')
        if self._mount_given or not frame or frame == self._base_frame.lstrip('/'):
            return self._mount
        mount = self._tf_mounts.get(frame)
        if mount is not None:
            return mount
        buffer = self._tf_buffer()
        if buffer is None:
            return self._mount
        try:
            from rclpy.time import Time
            transform = buffer.lookup_transform(self._base_frame, frame, Time())
        except Exception as err:  # noqa: BLE001 -- tf2's lookup errors: not there yet
            self._skip('waiting', f'no transform from {frame!r} to {self._base_frame!r} yet '
                       f'({type(err).__name__}; set imu_mount.* to give the mounting '
                       'instead)', True)
            return None
        rotation = transform.transform.rotation
        q = (rotation.x, rotation.y, rotation.z, rotation.w)
        norm = math.sqrt(sum(v * v for v in q))
        if not math.isfinite(norm) or abs(norm - 1.0) > 0.01:
            self._skip('waiting', f'the transform from {frame!r} to {self._base_frame!r} has '
                       'no valid rotation', True)
            return None
        mount = self._tf_mounts[frame] = _rotation_rows(tuple(v / norm for v in q))
        self._logger.info(f'{self._topic_name()}: IMU frame {frame!r} in '
                          f'{self._base_frame!r} from TF')
        return mount

    def _tf_buffer(self):
        """Return a tf2_ros Buffer (with its listener), or None where tf2_ros is absent."""
        if self._tf is not None or self._tf_warned:
            return self._tf
        try:
            from tf2_ros import Buffer, TransformListener
        except ImportError as err:
            self._tf_warned = True
            self._logger.warning(
                f"{self._topic_name()}: tf2_ros cannot be imported ({err}): the IMU's "
                "frame_id is not looked up; its axes are taken as base_frame's turned by "
                'imu_mount.roll/pitch/yaw (all 0: aligned). Set them for an IMU mounted '
                'otherwise (roll pi: z down or NED), or install tf2_ros.')
            return None
        self._tf = Buffer()
        self._tf_listener = TransformListener(self._tf, self._node)
        return self._tf

    # The watchdog -----------------------------------------------------------------------

    def _topic_name(self) -> str:
        return '' if self.topic is None else self.topic.topic_name

    def _reason(self, now_ns: int) -> str:
        """Say why no sample is usable: the graph first, then what the samples were."""
        topic = self.topic
        last = topic.count.last_ns
        if last is not None and now_ns - last <= GRACE * _NS and self._why:
            return self._why
        try:
            infos = self._node.get_publishers_info_by_topic(topic.topic_name)
        except Exception:  # noqa: BLE001 -- the graph is gone during shutdown
            infos = []
        if not infos:
            return 'no publisher (is imu_topic right, the topic remapped?)'
        ours = [info for info in infos if info.topic_type == _IMU_TYPE]
        if not ours:
            kinds = ', '.join(sorted({info.topic_type for info in infos}))
            return f'its publishers are of another type ({kinds}), not {_IMU_TYPE}'
        if last is None:
            return f'no message yet ({len(ours)} publisher{"s" * (len(ours) != 1)})'
        return (f'no message for {(now_ns - last) / _NS:.0f} s ({len(ours)} '
                f'publisher{"s" * (len(ours) != 1)})')

    def report(self, report) -> None:
        """Add the intake's counts; ``WARN`` with the reason when no sample is usable."""
        report.add('imu samples used', self.counts['used'])
        report.add('imu samples dropped', sum(n for kind, n in self.counts.items()
                                              if kind != 'used'))
        report.add('imu frame', 'imu_mount.* parameters' if self._mount_given or not
                   self._tf_mounts else 'TF (' + ', '.join(sorted(self._tf_mounts)) + ')')
        report.add('imu heading rate', 'from the orientation (tilt corrected)'
                   if self.orientation_used else 'body z rate (no usable orientation)')
        if self.topic is None:
            return
        now_ns = monotonic_ns()
        since = self._usable_ns if self._usable_ns is not None else self._start_ns
        if now_ns - since < GRACE * _NS:
            if self._warned_ns is not None and self._usable_ns is not None:
                self._warned_ns = None
                self._logger.info(f'{self.topic.topic_name}: usable gyro samples again')
            return
        text = (f'{self.topic.topic_name}: no usable gyro sample for '
                f'{(now_ns - since) / _NS:.0f} s: {self._reason(now_ns)}')
        report.merge(WARN, text)
        if self._warned_ns is None or now_ns - self._warned_ns >= WARN_PERIOD * _NS:
            self._warned_ns = now_ns
            self._logger.warning(f"{text}; the heading is the encoders'")
