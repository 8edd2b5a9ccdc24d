"""odometry_node with imu_topic under hostile input (issue 35): each failed on the old node."""

import math

from helpers.gyro_drive import gyro_drive, true_heading
import numpy as np
import pytest
from test_odometry_node_imu import AURIGA, Graph, planar, yaws
from tracked_kinematics.ros.health import ERROR

pytestmark = pytest.mark.ros

T0 = 100.0  # s: the drive played again 30 s earlier keeps positive stamps


@pytest.fixture
def graph(ros_context, executor, capfd):
    def make(overrides=None):
        return Graph(ros_context, executor, capfd, overrides)
    return make


def drive(seconds=10.0, seed=0, **kwargs):
    t, left, right, tg, wg = gyro_drive(
        AURIGA, **{'seconds': seconds, 'still': 3.5, 'gyro_rate': 100.0, 'seed': seed,
                   **kwargs})
    return T0 + t, left, right, T0 + tg, wg


def finite(msgs):
    return all(np.all(np.isfinite(planar(m.pose.covariance))) and math.isfinite(
        m.pose.pose.position.x) and math.isfinite(m.twist.twist.angular.z) for m in msgs)


def test_stamps_going_back_with_the_imu_on(graph):
    # Before: TypeError in GyroOdometry._gyro_increment, the node exited 1.
    g = graph()
    t, left, right, tg, wg = drive()
    first = g.feed(t, left, right, tg, wg)
    assert g.node.odometry.source == 'gyro'
    # The same drive again, 30 s earlier (a bag played in a loop), the tracks carrying on.
    again = g.feed(t - 30.0, left + left[-1], right + right[-1], tg - 30.0, wg)
    assert finite(first + again)
    assert g.node.odometry.source == 'gyro'
    truth = true_heading(AURIGA, t, left, right)
    turned = yaws(again)[-1] - yaws(again)[0]
    assert turned == pytest.approx(truth[-1] - truth[1], abs=0.05)


@pytest.mark.parametrize('value', [
    1e20, math.nan,
    # The gates refuse these as they refuse 1e20 and NaN: make stress sends them too.
    *(pytest.param(v, marks=pytest.mark.long) for v in (1e200, math.inf, -1e308))])
def test_one_garbage_sample(graph, value):
    # Before: 1e200 raised OverflowError (the node died), 1e20 froze the heading for good.
    g = graph()
    t, left, right, tg, wg = drive(seconds=16.0)
    wg = wg.copy()
    wg[np.searchsorted(tg, T0 + 6.0)] = value
    msgs = g.feed(t, left, right, tg, wg)
    assert finite(msgs)
    assert g.stderr.warnings('odometry_node', 'heading from the encoders until')
    # A clean drive afterwards turns right (the truth from 9 s on, within 0.03 rad).
    truth = true_heading(AURIGA, t, left, right)
    after = np.flatnonzero(t[1:] >= T0 + 9.0)
    turned = yaws(msgs)[after[-1]] - yaws(msgs)[after[0]]
    assert turned == pytest.approx(truth[1:][after[-1]] - truth[1:][after[0]], abs=0.03)
    assert g.node.odometry.source == 'gyro'


def test_an_upside_down_imu_is_refused_with_an_error(graph):
    # Before: the heading turned the wrong way with OK on /diagnostics.
    g = graph()
    t, left, right, tg, wg = drive(seconds=16.0)
    g.feed(t, left, right, tg, -wg)
    report = {v.key: v.value for v in g.node.health.report().values}
    status = g.node.health.report()
    assert g.node.odometry.source == 'encoders'
    assert status.level == ERROR and 'other way' in status.message
    assert 'upside down' in report['heading source reason']
    # Never adapted (adapt_slip is on), so nothing to push: the terrain file's ICRs in force.
    icr = g.node.odometry.icr
    assert (icr.y_left, icr.y_right) == pytest.approx((AURIGA.y_left, AURIGA.y_right), abs=1e-12)
    assert float(report['icr.y_left in force (m)']) == pytest.approx(AURIGA.y_left)


@pytest.mark.parametrize('wild, warning', [
    ('nanosec', 'nanosec >= 1e9'),
    ('negative', 'zero or negative stamp'),
    ('second_publisher', 'a gyro stamp not after the last one (two publishers on the topic'),
])
def test_wild_imu_stamps_are_dropped_and_named(graph, wild, warning):
    # Before: a stamp with nanosec 4e9 (4 s ahead) shut the gyro out for 4 s with OK on
    # /diagnostics; a second publisher 3 s ahead owned the buffer (the true samples dropped
    # in silence); a negative stamp was called a zero one.
    from test_odometry_node_imu_input import imu
    g = graph()
    t, left, right, tg, wg = drive(seconds=10.0)
    at = int(np.searchsorted(tg, T0 + 5.0))
    msgs = [imu(s, (0.0, 0.0, w)) for s, w in zip(tg, wg)]
    if wild == 'nanosec':
        msgs[at].header.stamp.nanosec = 4_000_000_000
    elif wild == 'negative':
        msgs[at].header.stamp.sec = -5
    else:   # from 5 s on, another publisher's samples 3 s ahead between the true ones
        msgs = msgs[:at] + [m for s, w, m in zip(tg[at:], wg[at:], msgs[at:])
                            for m in (m, imu(s + 3.0 + 1e-3, (0.0, 0.0, 1.0)))]
        tg = np.r_[tg[:at], np.repeat(tg[at:], 2)]
    seen = []
    odom = g.feed(t, left, right, tg, msgs, lambda s: seen.append(g.node.odometry.source))
    assert finite(odom)
    assert g.stderr.warnings('odometry_node', warning)
    # The gyro never let go once in use, and turned right.
    assert set(seen[seen.index('gyro'):]) == {'gyro'}
    truth = true_heading(AURIGA, t, left, right)
    assert yaws(odom)[-1] - yaws(odom)[0] == pytest.approx(truth[-1] - truth[1], abs=0.03)
    assert g.node.health.report().level == b'\x00'


@pytest.mark.parametrize('offset', [-1.0, 2.0])
def test_an_imu_on_a_clock_seconds_off_is_refused_naming_the_clock(graph, offset):
    # Before: 2 s ahead, fused on and off (heading 1.4 rad off at the end, OK on
    # /diagnostics) or refused as 'on another axis'; 1 s behind, never used, with OK.
    from test_odometry_node_imu_input import imu
    g = graph()
    t, left, right, tg, wg = drive(seconds=10.0)
    # Sent as they come (at their true times), stamped on a clock `offset` s off.
    odom = g.feed(t, left, right, tg, [imu(s + offset, (0.0, 0.0, w)) for s, w in zip(tg, wg)])
    assert finite(odom)
    status = g.node.health.report()
    assert g.node.odometry.source == 'encoders' and status.level == ERROR
    # After imu_delay (0.05 s).
    assert f"the gyro's stamps are {offset - 0.05:+.3g} s" in status.message
    assert 'another clock' in status.message
