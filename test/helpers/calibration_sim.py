"""
A calibration drive in the core simulator: protocol + supervisor + a slipping vehicle.

What the closed-loop test (test/ros/test_calibration_closed_loop.py) runs through three
nodes, here in one loop and without ROS: the supervisor ticks at 20 Hz on the geofence pose
(the true pose with the pose reference; gyro heading and encoder distance, as
:class:`FenceOdometry`, with the IMU), its ``(v, w)`` goes to the tracks through the ideal
kinematics of the nominal track width (cmd_vel_translator without limits), the vehicle is the
simulator's (auriga_alpha on hard floor by default: it turns about half as fast as commanded).
"""

from dataclasses import dataclass
import math

from tracked_kinematics.core.plan.calibration_protocol import FenceOdometry
from tracked_kinematics.core.plan.supervisor import Inputs, Supervisor, SupervisorConfig
from tracked_kinematics.core.sim.live import LiveSimulator
from tracked_kinematics.core.sim.simulation import TwistTable
from tracked_kinematics.core.sim.terrains import TERRAINS
from tracked_kinematics.params.vehicles import load_vehicle

#: The node's tighter fence fractions with the IMU (ros/calibration_drive_node.py, IMU_FENCE).
IMU_FENCE = {'plan_fraction': 0.8, 'guard_fraction': 0.87}
DT = 0.01           # s, the simulator's step
TICKS = 5           # simulator steps per supervisor tick (20 Hz)
_VEHICLES = {}


def vehicle(name='auriga_alpha', terrain='hard_floor'):
    """Return the robot and its dynamics (cached: a table takes a while to build)."""
    if (name, terrain) not in _VEHICLES:
        robot = load_vehicle(name).robot
        _VEHICLES[name, terrain] = (robot, TwistTable(TERRAINS[terrain].apply(robot.vehicle)))
    return _VEHICLES[name, terrain]


@dataclass
class Drive:
    """What a simulated drive did."""

    time: float                 # sim time from start to finished (or to the limit), s
    state: str                  # the supervisor's last state
    returns: int                # returns to the centre
    max_distance: float         # farthest true pose from the start, m
    events: list                # the supervisor's (t, state, reason)
    poses: list                 # true (t, x, y, theta, travel left, travel right) per tick


def drive(steps, config: SupervisorConfig, reference='pose', track_width=0.42,
          name='auriga_alpha', terrain='hard_floor', limit=None) -> Drive:
    """
    Drive ``steps`` under the supervisor with the deadman held until it finishes.

    ``limit``: sim time after which to give up, s (default three times the protocol).
    """
    robot, table = vehicle(name, terrain)
    sim = LiveSimulator(robot, DT, table)
    sup = Supervisor(steps, config)
    fence = FenceOdometry()
    limit = limit if limit is not None else 3.0 * sum(s.duration for s in steps) + 60.0
    t0 = None
    poses = []
    max_distance = 0.0
    while True:
        t = sim.t
        state = sim.state
        if reference == 'pose':
            pose = state.pose
        else:
            pose = fence.pose
        out = sup.update(Inputs(t, True, t, t, t, tuple(pose)))
        if t0 is None:
            sup.start(Inputs(t, True, t, t, t, tuple(pose)))
            t0 = t
            continue
        if out.state in ('finished', 'stopped') or t - t0 > limit:
            break
        half = 0.5 * track_width * out.w
        steps_ = sim.step_many([(out.v - half, out.v + half)] * TICKS)
        prev = state.travel
        for k in range(len(steps_)):
            still = abs(steps_.nominal[k, 0]) < 0.005 and abs(steps_.nominal[k, 1]) < 0.005
            fence.add_gyro(float(steps_.t[k]), float(steps_.twist[k, 2]), still)
            travel = steps_.travel[k]
            fence.add_travel(travel[0] - prev[0], travel[1] - prev[1])
            prev = travel
        x, y, theta = sim.state.pose
        poses.append((sim.t, x, y, theta, *sim.state.travel))
        max_distance = max(max_distance, math.hypot(x, y))
    events = sup.events
    returns = sum(1 for _, s, _ in events if s == 'returning')
    return Drive(sim.t - t0, sup.state, returns, max_distance, events, poses)


def config(radius=3.0, reference='pose', **kwargs) -> SupervisorConfig:
    """Return the node's supervisor configuration for ``reference`` (default caps)."""
    extra = IMU_FENCE if reference == 'imu' else {}
    return SupervisorConfig(geofence_radius=radius, **{**extra, **kwargs})
