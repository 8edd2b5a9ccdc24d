"""Simulated runs recorded with their commands as setpoints, Twist or TwistStamped cmd_vel."""

import numpy as np
from tracked_kinematics.offline.bags import BagWriter

T0_NS = 1_700_000_000 * 1_000_000_000
JOINTS = ['left_sprocket_joint', 'right_sprocket_joint']


def write_commands_bag(path, run, track_width, commands='twist', rate=20.0,
                       gt_topic='/ground_truth/pose', cmd_vel_topic='/cmd_vel',
                       command_span=None):
    """
    Record a simulated run (``simulate_bag``'s :class:`Run`) with its commands.

    Parameters
    ----------
    commands : {'setpoints', 'twist', 'twist_stamped', 'none'}
        Per-track std_msgs/Float64 setpoints, or the body twist whose ideal inverse with
        ``track_width`` gives the commanded track speeds back (``v = (l + r) / 2``, ``w = (r -
        l) / B``), as geometry_msgs/Twist or TwistStamped; or none.
    rate : float
        Rate of the command messages, Hz (each the command in force at its time).
    command_span : tuple of float, optional
        Only commands within this time span, s (an operator drove the rest).

    """
    dt = float(run.t[1] - run.t[0])
    every = max(1, int(round(1.0 / (rate * dt))))
    cmd_idx = np.arange(0, len(run.t), every)
    if command_span is not None:
        cmd_idx = cmd_idx[(run.t[cmd_idx] >= command_span[0])
                          & (run.t[cmd_idx] <= command_span[1])]
    if commands == 'none':
        cmd_idx = cmd_idx[:0]
    events = [(T0_NS + int(round(t * 1e9)), 0, k) for k, t in enumerate(run.t)]
    events += [(T0_NS + int(round(run.t[k] * 1e9)), 1, k) for k in cmd_idx]
    events += [(T0_NS + int(round(t * 1e9)), 2, k) for k, t in enumerate(run.gt_t)]
    events.sort()
    with BagWriter(path) as bag:
        for stamp, kind, k in events:
            if kind == 0:
                bag.write('/joint_states', stamp, bag.joint_state(
                    stamp, JOINTS, run.joint_position[k], run.joint_velocity[k]))
            elif kind == 2:
                bag.write(gt_topic, stamp, bag.pose_stamped(stamp, *run.gt_pose[k]))
            else:
                left, right = (float(v) for v in run.commands[k])
                if commands == 'setpoints':
                    bag.write('/left_track/setpoint', stamp, bag.float64(left))
                    bag.write('/right_track/setpoint', stamp, bag.float64(right))
                    continue
                v, w = 0.5 * (left + right), (right - left) / track_width
                message = (bag.twist(v, w) if commands == 'twist'
                           else bag.twist_stamped(stamp, v, w))
                bag.write(cmd_vel_topic, stamp, message)
