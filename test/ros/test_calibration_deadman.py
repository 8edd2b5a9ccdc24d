"""calibration_deadman: the deadman and the status of calibration_drive without the ros2 CLI."""

import json

from helpers.ros_helpers import ConsoleScript, spin_until
import pytest
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool, String
from std_srvs.srv import Trigger
from tracked_kinematics.ros.calibration_deadman import KeyHold, parse, status_line


def test_a_held_key_stays_held_through_the_first_repeat_delay_then_releases_quickly():
    hold = KeyHold()
    assert not hold.held(0.0)
    hold.press(0.0)
    assert hold.held(0.6)                # the terminal's auto-repeat has not begun yet
    for k in range(20):                  # auto-repeat every 33 ms from 0.66 s
        hold.press(0.66 + 0.033 * k)
        assert hold.held(0.66 + 0.033 * k + 0.01)
    last = 0.66 + 0.033 * 19
    assert hold.held(last + 0.14)
    assert not hold.held(last + 0.16)    # let go: released 0.15 s after the last repeat
    assert not hold.held(last + 0.17)
    hold.press(5.0)
    hold.release()                       # another key: released at once
    assert not hold.held(5.0)


def test_a_single_press_without_repeats_is_released_after_the_repeat_delay():
    hold = KeyHold()
    hold.press(1.0)
    assert hold.held(1.79) and not hold.held(1.81)


def test_status_lines():
    assert status_line({'state': 'running', 'reason': '', 'step': 2, 'steps': 30,
                        'step_kind': 'arc', 'distance': 1.234, 'phase': 'drive',
                        'exit_status': None}) == 'running step 3/30 arc 1.23 m from the centre'
    assert status_line({'state': 'finished', 'reason': 'all 30 steps driven', 'step': 30,
                        'steps': 30, 'phase': 'done', 'exit_status': 0}) == \
        'finished (all 30 steps driven) step 30/30 [done] exit status 0'


def test_options_and_ros_arguments_are_split():
    options, ros = parse(['calibration_deadman', '--hold', '--rate', '10', '--ros-args', '-r',
                          'deadman:=/dm'])
    assert options.hold and options.rate == 10.0 and options.drive == '/calibration_drive'
    assert ros == ['calibration_deadman', '--ros-args', '-r', 'deadman:=/dm']
    with pytest.raises(SystemExit):
        parse(['calibration_deadman', '--rate', '1e308'])


def test_without_a_terminal_it_asks_for_hold(tmp_path):
    with ConsoleScript('calibration_deadman', tmp_path=tmp_path) as tool:
        assert tool.process.wait(30) == 2
    assert 'give --hold' in tool.stderr_path.read_text()


@pytest.mark.ros
def test_hold_presses_the_deadman_starts_the_drive_shows_its_status_and_ends_with_it(
        ros_context, executor, tmp_path):
    node = Node('calibration_drive', context=ros_context)
    executor.add_node(node)
    seen, starts = [], []
    node.create_subscription(Bool, '/deadman', lambda m: seen.append(m.data), 10)
    reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    status = node.create_publisher(String, '~/status', reliable)

    def start(request, response):
        starts.append(list(seen))
        response.success, response.message = True, 'started: 30 steps'
        return response

    node.create_service(Trigger, '~/start', start)
    try:
        with ConsoleScript('calibration_deadman', '--hold', '--start', tmp_path=tmp_path) as tool:
            # ~/start is called once the deadman is held. (It publishes false for 0.5 s after
            # it sees the subscriber first; under load this side may match it later than that,
            # so the test cannot count on receiving those. A first true arms the drive's
            # deadman; the false that re-arms a latched one is checked below.)
            assert spin_until(executor, lambda: True in seen and starts, timeout=20)
            assert starts[0][-1] is True
            assert spin_until(executor, lambda: status.get_subscription_count() > 0)
            state = {'state': 'running', 'reason': '', 'step': 0, 'steps': 30,
                     'step_kind': 'straight', 'distance': 0.5, 'phase': 'drive',
                     'exit_status': None}
            status.publish(String(data=json.dumps(state)))
            # The drive latched a deadman that went stale: --hold lets go and presses again.
            n = len(seen)
            status.publish(String(data=json.dumps(
                {**state, 'state': 'paused', 'reason': 'deadman not held within 0.3 s'})))
            assert spin_until(executor, lambda: False in seen[n:], timeout=10)
            k = n + seen[n:].index(False)
            assert spin_until(executor, lambda: True in seen[k:], timeout=10)
            status.publish(String(data=json.dumps(state)))
            status.publish(String(data=json.dumps({**state, 'state': 'finished', 'step': 30,
                                                   'phase': 'done', 'exit_status': 0})))
            assert spin_until(executor, lambda: tool.process.poll() is not None, timeout=20)
            assert tool.process.returncode == 0
            assert seen[-1] is False             # released when the drive is done
        out = tool.stdout_path.read_text()
        assert 'start: started: 30 steps' in out
        assert 'running step 1/30 straight 0.50 m from the centre' in out
        assert 'the deadman went stale: pressing it again (--hold)' in out
        assert 'calibration drive done (exit status 0)' in out
    finally:
        executor.remove_node(node)
        node.destroy_node()
