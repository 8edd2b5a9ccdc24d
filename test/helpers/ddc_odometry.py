"""
diff_drive_controller's odometry, transcribed, to compare ours with.

A line-by-line Python transcription of ros2_controllers' ``diff_drive_controller/src/
odometry.cpp`` (``Odometry::update``, ``updateFromVelocity``, ``integrateExact``,
``integrateRungeKutta2``, the rolling-mean twist) and of what ``diff_drive_controller.cpp``
feeds it: the effective geometry of ``on_configure`` (separation x multiplier, radius x
side multiplier) and, in ``update_and_write_commands``, the mean position of each side's
wheels with ``position_feedback`` true. Written from the published sources' formulas, in
their order of operations (C++ doubles are Python floats), not from our code.
"""

from collections import deque
import math


class RollingMean:
    """rcppmath::RollingMeanAccumulator: the mean of the last ``size`` values."""

    def __init__(self, size):
        self.values = deque(maxlen=size)

    def accumulate(self, value):
        self.values.append(value)

    def mean(self):
        return sum(self.values) / len(self.values) if self.values else 0.0


class DdcOdometry:
    """
    ``diff_drive_controller::Odometry`` with ``setWheelParams`` already applied.

    Attributes ``x``, ``y``, ``heading`` (continuous), ``linear``, ``angular`` as in C++.
    """

    def __init__(self, wheel_separation, left_wheel_radius, right_wheel_radius,
                 velocity_rolling_window_size=10):
        self.wheel_separation = wheel_separation
        self.left_wheel_radius = left_wheel_radius
        self.right_wheel_radius = right_wheel_radius
        self.window = velocity_rolling_window_size
        self.timestamp = 0.0
        self.x = self.y = self.heading = 0.0
        self.linear = self.angular = 0.0
        self.left_wheel_old_pos = self.right_wheel_old_pos = 0.0
        self.reset_accumulators()

    def reset_accumulators(self):
        self.linear_accumulator = RollingMean(self.window)
        self.angular_accumulator = RollingMean(self.window)

    def init(self, time):
        self.reset_accumulators()
        self.timestamp = time

    def update(self, left_pos, right_pos, time):
        """Odometry::update: wheel positions (rad) at ``time`` (s)."""
        dt = time - self.timestamp
        if dt < 0.0001:
            return False  # Interval too small to integrate with
        left_wheel_cur_pos = left_pos * self.left_wheel_radius
        right_wheel_cur_pos = right_pos * self.right_wheel_radius
        left_wheel_est_vel = left_wheel_cur_pos - self.left_wheel_old_pos
        right_wheel_est_vel = right_wheel_cur_pos - self.right_wheel_old_pos
        self.left_wheel_old_pos = left_wheel_cur_pos
        self.right_wheel_old_pos = right_wheel_cur_pos
        self.update_from_velocity(left_wheel_est_vel, right_wheel_est_vel, time)
        return True

    def update_from_velocity(self, left_vel, right_vel, time):
        """Odometry::updateFromVelocity: per-update wheel travel (m)."""
        dt = time - self.timestamp
        linear = (left_vel + right_vel) * 0.5
        angular = (right_vel - left_vel) / self.wheel_separation
        self.integrate_exact(linear, angular)
        self.timestamp = time
        self.linear_accumulator.accumulate(linear / dt)
        self.angular_accumulator.accumulate(angular / dt)
        self.linear = self.linear_accumulator.mean()
        self.angular = self.angular_accumulator.mean()
        return True

    def integrate_runge_kutta2(self, linear, angular):
        direction = self.heading + angular * 0.5
        self.x += linear * math.cos(direction)
        self.y += linear * math.sin(direction)
        self.heading += angular

    def integrate_exact(self, linear, angular):
        if math.fabs(angular) < 1e-6:
            self.integrate_runge_kutta2(linear, angular)
        else:
            heading_old = self.heading
            r = linear / angular
            self.heading += angular
            self.x += r * (math.sin(self.heading) - math.sin(heading_old))
            self.y += -r * (math.cos(self.heading) - math.cos(heading_old))

    @property
    def pose(self):
        return self.x, self.y, self.heading


def ddc_from_parameters(params, velocity_rolling_window_size=10):
    """
    Build the odometry a DiffDriveController configures from its parameters (on_configure).

    ``params``: DDC parameter names to values; the multipliers default to 1 as in DDC, and
    ROS 1's single ``wheel_radius_multiplier`` is the default of both sides.
    """
    both = params.get('wheel_radius_multiplier', 1.0)
    wheel_separation = params.get('wheel_separation_multiplier', 1.0) * params['wheel_separation']
    left_wheel_radius = params.get('left_wheel_radius_multiplier', both) * params['wheel_radius']
    right_wheel_radius = params.get('right_wheel_radius_multiplier', both) * params['wheel_radius']
    return DdcOdometry(wheel_separation, left_wheel_radius, right_wheel_radius,
                       velocity_rolling_window_size)


def run_ddc(odometry, times, left_positions, right_positions):
    """
    Feed DDC's odometry as its update loop does; return the pose after every sample.

    ``left_positions`` / ``right_positions``: one row per sample, one column per wheel of the
    side; the side's mean position goes to ``Odometry::update`` (position_feedback true).
    The odometry is initialised at the first sample's time (``on_activate``).
    """
    odometry.init(float(times[0]))
    poses = []
    for time, left, right in zip(times, left_positions, right_positions):
        left_feedback_mean = 0.0
        right_feedback_mean = 0.0
        for value in left:
            left_feedback_mean += float(value)
        for value in right:
            right_feedback_mean += float(value)
        left_feedback_mean /= len(left)
        right_feedback_mean /= len(right)
        odometry.update(left_feedback_mean, right_feedback_mean, float(time))
        poses.append(odometry.pose)
    return poses


# --- our side, as odometry_node computes it -------------------------------------------------


def run_ours(icr, sprocket_radius, times, left_positions, right_positions, max_dt=0.5):
    """
    Our odometry on the same joint data, through the path odometry_node takes.

    odometry_node's joint_states input averages each side's joints, turns the positions into
    nominal travel with :class:`~tracked_kinematics.core.encoders.IncrementTracker`
    (``factor = sprocket_radius``) and integrates every step with
    :class:`~tracked_kinematics.core.odometry.Odometry`. Returns the pose after every
    sample and the Odometry (for its twist).
    """
    from tracked_kinematics.core.encoders import IncrementTracker, Status
    from tracked_kinematics.core.odometry import Odometry

    tracker = IncrementTracker(max_dt)
    odometry = Odometry(icr)
    poses = []
    for time, left, right in zip(times, left_positions, right_positions):
        left_mean = sum(float(v) for v in left) / len(left)
        right_mean = sum(float(v) for v in right) / len(right)
        status, d_left, d_right, dt = tracker.update(
            int(round(time * 1e9)), 'position', left_mean, right_mean, sprocket_radius)
        if status == Status.STEP:
            assert odometry.update(d_left, d_right, dt)
        else:
            assert status == Status.FIRST, status
        poses.append(odometry.pose)
    return poses, odometry


def run_ours_vectorised(icr, sprocket_radius, left_positions, right_positions):
    """Our vectorised core on the same joint data: final pose of ``integrate``."""
    import numpy as np
    from tracked_kinematics.core.encoders import mean_over_joints, travel_from_positions
    from tracked_kinematics.core.integration import integrate
    from tracked_kinematics.core.kinematics import forward, true_speeds

    d_left = travel_from_positions(mean_over_joints(left_positions), sprocket_radius)
    d_right = travel_from_positions(mean_over_joints(right_positions), sprocket_radius)
    x, y, theta = integrate(*forward(*true_speeds(d_left, d_right, icr), icr))
    return np.stack([x, y, theta], -1)


def wheel_stream(times, speed_left, speed_right, radius, wheels=1, rng=None):
    """
    Joint positions (rad) of wheels driven at the given track speeds (m/s), from 0.

    Each speed holds over the interval that ends at its sample (the first is unused). With
    ``wheels`` > 1 and an ``rng``, each wheel of a side gets a small random offset from the
    side's position that averages out, as wheels on one side of a skid-steer robot do.
    """
    import numpy as np

    dt = np.diff(times)
    left = np.concatenate([[0.0], np.cumsum(np.asarray(speed_left)[1:] * dt)]) / radius
    right = np.concatenate([[0.0], np.cumsum(np.asarray(speed_right)[1:] * dt)]) / radius
    left = np.repeat(left[:, None], wheels, axis=1)
    right = np.repeat(right[:, None], wheels, axis=1)
    if wheels > 1 and rng is not None:
        for side in (left, right):
            offset = rng.normal(0.0, 1e-3, side.shape)
            offset -= offset.mean(axis=1, keepdims=True)
            side += offset
            side[0] = 0.0
    return left, right
