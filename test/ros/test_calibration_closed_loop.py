"""
The calibration drive in closed loop (issue 22's checks), faster than real time.

tracked_simulator (auriga_alpha on hard floor) + cmd_vel_translator (no limits, so no
deceleration ramp) + calibration_drive (the pose reference, or the gyro alone), as console
scripts in sim time; the test holds the deadman, releases it once mid-drive, and watches
everything.
"""

import json
import math
from pathlib import Path
import time

from geometry_msgs.msg import Twist
from helpers.ros_helpers import ConsoleScript, spin_until
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool, Float64, String
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.offline.bag_simulation import simulate_bag
from tracked_kinematics.offline.bags import EncoderSource, GroundTruthSource, read_recording
from tracked_kinematics.offline.cli.tracked_kinematics_demo import dead_reckon
from tracked_kinematics.params import icr_from_values, read_params_file

pytestmark = pytest.mark.ros

RTF = 3.0
RELEASE_RTF = 0.05     # while the deadman release is timed (see below)
DURATION = 60.0          # s of protocol motion (sim time)
FENCE = 3.0
TERRAIN = '/**:\n  ros__parameters:\n    track_width: 0.42\n    sprocket_radius: 0.1\n'
# Every node of the loop in a namespace of its own (/clock stays global: it is absolute).
NS = '/closed_loop'


class Watcher:
    """The test's node, in sim time: holds the deadman and records what the others do."""

    def __init__(self, context, executor):
        self.node = Node('closed_loop_watcher', context=context, namespace=NS,
                         parameter_overrides=[Parameter('use_sim_time', value=True)])
        executor.add_node(self.node)
        reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.deadman_pub = self.node.create_publisher(Bool, 'deadman', 10)
        self.cmds = []
        self.setpoints = {'left': [], 'right': []}
        self.start = None
        self.max_distance = 0.0
        self.status = {}
        self.node.create_subscription(Twist, 'cmd_vel', self.cmds.append, reliable)
        for side in self.setpoints:
            self.node.create_subscription(
                Float64, f'{side}_track/setpoint',
                lambda m, side=side: self.setpoints[side].append((self.now(), m.data)), reliable)
        self.node.create_subscription(Odometry, 'ground_truth/odom', self._on_truth, reliable)
        self.node.create_subscription(String, 'calibration_drive/status',
                                      lambda m: self.status.update(json.loads(m.data)), 10)

    def now(self):
        return self.node.get_clock().now().nanoseconds * 1e-9

    def _on_truth(self, msg):
        # The simulated robot stands still until the drive starts: its first pose is the
        # start (taking the pose when the status says running would depend on which of the
        # two subscriptions a loaded executor serves first).
        p = msg.pose.pose.position
        if self.start is None:
            self.start = (p.x, p.y)
        self.max_distance = max(self.max_distance,
                                math.hypot(p.x - self.start[0], p.y - self.start[1]))


def _zero_from(setpoints, since):
    """When a side's setpoints, received after ``since``, became zero for good (inf: never)."""
    nonzero = [k for k, (_, v) in enumerate(setpoints) if v != 0.0]
    first = nonzero[-1] + 1 if nonzero else 0
    return max(setpoints[first][0], since) if first < len(setpoints) else math.inf


def _heldout_errors(tmp_path, fitted: IcrParams, paths=3, duration=60.0):
    """
    Mean final position and heading errors of ideal drive and of the fit on new paths.

    Headings are compared unwrapped (both are continuous), so a dead reckoning that has
    turned a whole extra turn counts 2 pi, not 0.
    """
    ideal = IcrParams.ideal(fitted.track_width)
    errors = []
    for k, manoeuvres in enumerate(('random', 'sweep', 'mixed')[:paths]):
        sim = simulate_bag(tmp_path / f'heldout{k}', 'auriga_alpha', manoeuvres=manoeuvres,
                           duration=duration, seed=11 + k, storage='mcap')
        rec = read_recording(sim.bag, EncoderSource(sprocket_radius=0.1),
                             ground_truth=GroundTruthSource('/ground_truth/pose'))
        truth = sim.run.pose[-1]
        ends = [dead_reckon(icr, rec.left, rec.right)[-1] for icr in (ideal, fitted)]
        errors.append([[float(np.hypot(*(end[:2] - truth[:2]))),
                        abs(float(end[2] - truth[2]))] for end in ends])
    # [ideal, fitted] x [position, heading]
    return np.mean(errors, axis=0)


# Both long (make stress): the suite runs the same loop as the five-minute page's walk
# (test_five_minute_page), and the release and fence rules in process (test_calibration_drive).
@pytest.mark.long
@pytest.mark.parametrize('reference', ['pose', 'imu'])
def test_calibration_drive_in_closed_loop(ros_context, executor, tmp_path, reference):
    terrain = tmp_path / 'ideal.yaml'
    terrain.write_text(TERRAIN)
    out, bag = tmp_path / 'calibrated.yaml', tmp_path / 'drive'
    sim_time = ['-p', 'use_sim_time:=true', '-r', f'__ns:={NS}']
    watcher = Watcher(ros_context, executor)
    with ConsoleScript('tracked_simulator', '--ros-args', '-p', 'vehicle:=auriga_alpha',
                       '-p', 'terrain:=hard_floor', '-p', f'real_time_factor:={RTF}',
                       '-r', f'__ns:={NS}', tmp_path=tmp_path) as sim, \
            ConsoleScript('cmd_vel_translator', '--ros-args', '--params-file', terrain,
                          *sim_time, tmp_path=tmp_path) as translator, \
            ConsoleScript('calibration_drive', '--ros-args', '--params-file', terrain,
                          *sim_time, '-p', f'output:={out}', '-p', f'bag:={bag}',
                          '-p', f'duration:={DURATION}', '-p', f'geofence_radius:={FENCE}',
                          '-p', f'reference:={reference}',
                          '-p', 'auto_start:=true', '-p', 'deadman_timeout:=1.0',
                          '-p', 'encoder_timeout:=2.0', '-p', 'reference_timeout:=2.0',
                          tmp_path=tmp_path) as drive:
        def logs():
            return '\n'.join(p.output[-3000:] for p in (sim, translator, drive))

        simulator = AsyncParameterClient(watcher.node, f'{NS}/tracked_simulator')

        def set_real_time_factor(factor):
            assert simulator.wait_for_services(30.0), logs()
            future = simulator.set_parameters([Parameter('real_time_factor', value=factor)])
            assert spin_until(executor, future.done, 30.0), logs()
            assert future.result().results[0].successful, logs()

        def hold(held=True, seconds=0.02):
            watcher.deadman_pub.publish(Bool(data=held))
            spin_until(executor, lambda: False, seconds)

        # Held until the drive is well under way (a few steps done).
        deadline = time.monotonic() + 120.0
        while watcher.status.get('step', 0) < 3 and time.monotonic() < deadline:
            assert drive.process.poll() is None, logs()
            hold()
        # Moving (a step, or a return towards the centre: the guard decides which).
        assert watcher.status.get('state') in ('running', 'returning'), logs()
        # Release: the track setpoints are zero within 0.1 s of sim time. The bound is the
        # robot's, in its world's time; what it measures is three processes passing a
        # message on, which a loaded machine can hold up for a few hundred ms of wall time
        # (0.27 s was seen at real time). The world is slowed for the check (0.1 s of sim
        # time is 2 s of wall time at 0.05x), so that the machine's load is not measured.
        set_real_time_factor(RELEASE_RTF)
        released = watcher.now()
        n_left, n_right = len(watcher.setpoints['left']), len(watcher.setpoints['right'])
        deadline = time.monotonic() + 60.0
        while watcher.now() < released + 0.2 and time.monotonic() < deadline:
            hold(False)
        zero = [_zero_from(watcher.setpoints[side][n:], released)
                for side, n in (('left', n_left), ('right', n_right))]
        print(f'release to zero setpoints: {max(zero) - released:.3f} s of sim time')
        assert max(zero) - released <= 0.1, (zero, released)
        assert watcher.status['state'] == 'paused'
        set_real_time_factor(RTF)
        # Held again to the end; the drive fits and exits by itself.
        deadline = time.monotonic() + 600.0
        while drive.process.poll() is None and time.monotonic() < deadline:
            hold()
        assert drive.process.poll() == 0, logs()
    assert all(math.isfinite(c.linear.x) and math.isfinite(c.angular.z) for c in watcher.cmds)
    print(f'largest true distance from the start: {watcher.max_distance:.3f} m (fence {FENCE} m); '
          f'{len(watcher.cmds)} commands, all finite')
    assert watcher.max_distance <= FENCE + 0.2, watcher.max_distance

    truth = simulate_bag(tmp_path / 'truth', 'auriga_alpha', duration=30.0, seed=0,
                         storage='mcap').truth_icr
    fitted = icr_from_values(read_params_file(out))
    assert fitted.chi == pytest.approx(truth.chi, rel=0.03), (fitted, truth)
    (ideal_position, ideal_heading), (position, heading) = _heldout_errors(tmp_path, fitted)
    print(f'{reference}: chi {fitted.chi:.4f} (truth {truth.chi:.4f}, '
          f'{100 * (fitted.chi / truth.chi - 1):+.1f} %); held-out final errors: position '
          f'{position:.3f} m vs ideal {ideal_position:.3f} m '
          f'({100 * (position / ideal_position - 1):+.0f} %), heading {heading:.3f} rad vs '
          f'ideal {ideal_heading:.3f} rad ({100 * (heading / ideal_heading - 1):+.0f} %)')
    assert heading <= 0.2 * ideal_heading, (ideal_heading, heading)
    if reference == 'pose':
        assert position <= 0.2 * ideal_position, (ideal_position, position)
    assert Path(bag, 'metadata.yaml').is_file()
