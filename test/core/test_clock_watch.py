"""ClockWatch: a ROS clock that is invalid, goes back or stalls is a fault (issue 27)."""

import math

import pytest
from tracked_kinematics.core.clock_watch import ClockWatch


def test_an_advancing_clock_is_healthy_at_any_rate():
    watch = ClockWatch(0.5)
    # 0.05x and 50x real time: the ROS clock advances, slowly or fast.
    for k in range(100):
        assert watch.update(100.0 + 0.05 * 0.02 * k, 0.02 * k) == ''
    for k in range(100):
        assert watch.update(200.0 + 50 * 0.02 * k, 2.0 + 0.02 * k) == ''


def test_a_clock_that_stands_still_stalls_after_the_timeout_and_recovers():
    watch = ClockWatch(0.5)
    assert watch.update(10.0, 0.0) == ''
    assert watch.update(10.0, 0.5) == ''           # not longer than the timeout yet
    assert 'not advanced for 0.6 s' in watch.update(10.0, 0.6)
    assert watch.fault.startswith('the ROS clock has not advanced')
    assert watch.update(10.001, 0.7) == ''


def test_a_clock_that_goes_back_is_reported_once_then_followed():
    watch = ClockWatch(0.5)
    watch.update(10.0, 0.0)
    assert watch.update(9.75, 0.01) == 'the ROS clock went back 0.25 s'
    assert watch.update(9.76, 0.02) == ''


@pytest.mark.parametrize('ros_s', [None, math.nan, math.inf, -1.0, 0.0])
def test_an_unreadable_or_missing_clock_is_invalid(ros_s):
    watch = ClockWatch(0.5)
    assert watch.update(ros_s, 0.0).startswith('the ROS clock is invalid')
    assert watch.update(5.0, 0.1) == ''
