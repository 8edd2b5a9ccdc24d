"""
The odometry's twist fused by a filter at 20, 50 and 100 Hz: the same consistency (issue 37).

robot_localization takes each odometry message as an independent measurement. Three
odometry_nodes take one encoder stream (200 Hz, track noise as the model says) and publish at
20, 50 and 100 Hz; a 1-D Kalman filter of our own fuses each stream's ``v_x`` and ``w`` with the
published variances, and its NEES (1 when consistent) is the same at every rate: measured
0.93-1.16 for both at 20, 50 and 100 Hz, where the 1-s mean's covariance on every message (the
twist covariance before issue 37) gave 19-20, 44-51 and 81-100.
"""

import math

from helpers.encoder_stream import joint_state
from helpers.ros_helpers import spin_until
from nav_msgs.msg import Odometry as OdometryMsg
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from tracked_kinematics.core.covariance import body_jacobian
from tracked_kinematics.params import icr_from_values, read_params_file
from tracked_kinematics.ros.odometry_node import OdometryNode
from tracked_kinematics.share import config_file

pytestmark = pytest.mark.ros

TERRAIN = config_file('auriga_alpha_hard_floor.yaml')
VALUES = {k: v for k, v in read_params_file(TERRAIN).items() if k not in ('terrain', 'source')}
AURIGA = icr_from_values(VALUES)
RADIUS = VALUES['sprocket_radius']
K, FLOOR = 5e-5, 1e-9          # covariance.k_left = k_right (the Warthog fit's), covariance.floor
NOISE = {'covariance.k_left': K, 'covariance.k_right': K, 'covariance.floor': FLOOR,
         'covariance.turn': 0.0, 'covariance.slip': 0.0, 'covariance.timing': 0.0,
         'publish_tf': False}
RATE = 200.0                   # Hz, the encoders
SECONDS = 40.0
RATES = (20.0, 50.0, 100.0)    # Hz, the odometry messages
Q = {'v': 0.005, 'w': 0.005}   # random-walk densities of the true v_x and w, per s


def encoder_stream(seed=0):
    """Return stamps, measured cumulative travel per track and the true (v_x, w) per step."""
    rng = np.random.default_rng(seed)
    n = int(SECONDS * RATE)
    dt = 1.0 / RATE
    v = 0.3 + np.cumsum(rng.normal(scale=math.sqrt(Q['v'] * dt), size=n))
    w = 0.1 + np.cumsum(rng.normal(scale=math.sqrt(Q['w'] * dt), size=n))
    body = np.array(body_jacobian(AURIGA))
    # Nominal track speeds that give (v_x, w) through the model (rows 0 and 2 of B).
    speeds = np.linalg.solve(body[[0, 2]], np.vstack([v, w]))
    travel = speeds * dt
    measured = travel + rng.normal(size=travel.shape) * np.sqrt(K * np.abs(travel) + FLOOR)
    cumulative = np.hstack([np.zeros((2, 1)), np.cumsum(measured, axis=1)])
    t = 10.0 + np.arange(n + 1) * dt
    return t, cumulative, v, w


def kalman_nees(stamps, z, r, truth, q):
    """Return the mean NEES of a 1-D random-walk Kalman filter fusing ``z`` of variances ``r``."""
    x, p = z[0], r[0]
    nees = []
    for k in range(1, len(z)):
        p += q * (stamps[k] - stamps[k - 1])
        gain = p / (p + r[k])
        x += gain * (z[k] - x)
        p *= 1.0 - gain
        if stamps[k] - stamps[0] > 2.0:   # after the start
            nees.append((x - truth[k]) ** 2 / p)
    return float(np.mean(nees))


def test_the_fused_twist_is_as_consistent_at_20_50_and_100_hz(ros_context, executor):
    nodes, received = {}, {rate: [] for rate in RATES}
    for rate in RATES:
        name = f'odometry_{rate:.0f}hz'
        nodes[rate] = OdometryNode(
            context=ros_context,
            cli_args=['--ros-args', '-r', f'__node:={name}', '-r', f'odom:={name}/odom'],
            parameter_overrides=[Parameter(k, value=v) for k, v in
                                 {**VALUES, **NOISE, 'publish_rate': rate}.items()])
        executor.add_node(nodes[rate])
    from rclpy.node import Node
    driver = Node('encoder_driver', context=ros_context)
    executor.add_node(driver)
    qos = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
    for rate in RATES:
        driver.create_subscription(OdometryMsg, f'odometry_{rate:.0f}hz/odom',
                                   received[rate].append, qos)
    pub = driver.create_publisher(JointState, 'joint_states', QoSProfile(
        depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    assert spin_until(executor, lambda: pub.get_subscription_count() == 3
                      and all(n.count_subscribers(n.resolve_topic_name('odom')) for n in
                              nodes.values()))
    # Reliable subscriptions (they follow the publisher at their next check): none lost.
    assert spin_until(executor, lambda: all(
        n.encoder.inputs[0].reliability == ReliabilityPolicy.RELIABLE
        and not n.encoder.inputs[0].switching for n in nodes.values()))
    t, cumulative, v, w = encoder_stream()
    for start in range(0, len(t), 100):
        for k in range(start, min(start + 100, len(t))):
            pub.publish(joint_state(t[k], cumulative[:, k] / RADIUS))
        target = min(start + 100, len(t))
        assert spin_until(executor, lambda: all(n.encoder.received >= target
                                                for n in nodes.values()), 10.0)

    def last_stamp(msgs):
        return msgs[-1].header.stamp.sec + 1e-9 * msgs[-1].header.stamp.nanosec if msgs else 0
    assert spin_until(executor, lambda: all(
        last_stamp(received[rate]) > t[-1] - 1.5 / rate for rate in RATES), 30.0), \
        {rate: (len(msgs), last_stamp(msgs)) for rate, msgs in received.items()}
    for node in nodes.values():
        node.destroy_node()
    results = {}
    for rate in RATES:
        msgs = received[rate]
        stamps = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in msgs])
        cov = np.array([m.twist.covariance for m in msgs])
        # The steps each message covers (after the previous one, up to its stamp).
        ends = np.searchsorted(t, stamps - 1e-6) + 1
        for key, z, var, truth in (
                ('v', [m.twist.twist.linear.x for m in msgs], cov[:, 0], v),
                ('w', [m.twist.twist.angular.z for m in msgs], cov[:, 35], w)):
            # The truth of a message: the true mean over its interval (steps k end at t[k+1]).
            sums = np.concatenate([[0.0], np.cumsum(truth)])
            means = (sums[ends[1:] - 1] - sums[ends[:-1] - 1]) / (ends[1:] - ends[:-1])
            results[rate, key] = kalman_nees(stamps[1:], np.array(z[1:]), var[1:], means,
                                             Q[key])
    print({f'{rate:.0f} Hz {key}': round(nees, 3) for (rate, key), nees in results.items()})
    for key in ('v', 'w'):
        values = [results[rate, key] for rate in RATES]
        # Consistent (the mean of ~100-200 independent chi^2(1)) at every rate, and the same.
        assert all(0.7 < nees < 1.4 for nees in values), values
        assert max(values) / min(values) < 1.4, values
