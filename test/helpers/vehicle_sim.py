"""
A known vehicle for identification tests and benchmarks: encoder log plus exact ground truth.

The vehicle follows any core.models motion model; its nominal track speeds are constant
between encoder samples, and ground truth is its exact pose at the ground-truth times (the
motion is integrated on the union of both time grids, along arcs).
"""

import numpy as np

from tracked_kinematics.core.identify import Recording
from tracked_kinematics.core.models import ConstantIcr

# Auriga-alpha on hard floor, Martinez sec. 5.3 and 6, in ROS axes (docs/model.md).
B = 0.42
AURIGA = (0.353, -0.425, 0.032, 1.0072, 1.0275)


def drive(duration, rate=100.0, seed=0, legs=('straight', 'arc', 'spin'), speed=0.5,
          smooth=0.3):
    """
    Nominal track speeds of a manually driven path: straights, arcs and spins, both ways.

    Returns
    -------
    t : ndarray
        Encoder sample times, s.
    v_left, v_right : ndarray
        Nominal speed held over the interval that starts at each sample, m/s.

    """
    rng = np.random.default_rng(seed)
    n = int(round(duration * rate)) + 1
    v = np.zeros(n)
    w = np.zeros(n)
    k = 0
    while k < n:
        length = int(rng.uniform(2.0, 6.0) * rate)
        kind = legs[rng.integers(len(legs))]
        sign = rng.choice([-1.0, 1.0])
        if kind == 'straight':
            v[k:k + length] = sign * rng.uniform(0.3, 1.0) * speed * 2
        elif kind == 'arc':
            v[k:k + length] = rng.uniform(0.2, 1.0) * speed * rng.choice([-1.0, 1.0], p=[.2, .8])
            w[k:k + length] = sign * rng.uniform(0.2, 1.0)
        else:
            w[k:k + length] = sign * rng.uniform(0.4, 1.2)
        k += length
    window = max(1, int(smooth * rate))
    kernel = np.ones(window) / window
    v = np.convolve(v, kernel, mode='same')
    w = np.convolve(w, kernel, mode='same')
    return np.arange(n) / rate, v - 0.5 * B * w, v + 0.5 * B * w


def simulate(model, p, duration=120.0, enc_rate=100.0, gt_rate=10.0, seed=0, gt_phase=0.0,
             legs=('straight', 'arc', 'spin'), name='sim', stand=None):
    """
    Drive ``model`` with parameters ``p`` and record it.

    ``stand=(period, length)``: the vehicle stands still for the first ``length`` s of every
    ``period`` s.

    Returns
    -------
    Recording
        Cumulative nominal travel at the encoder times, exact ground truth at
        ``gt_phase + k / gt_rate``.

    """
    t, v_left, v_right = drive(duration, enc_rate, seed, legs)
    if stand is not None:
        still = t % stand[0] < stand[1]
        v_left, v_right = np.where(still, 0.0, v_left), np.where(still, 0.0, v_right)
    left = np.concatenate([[0.0], np.cumsum(v_left[:-1] * np.diff(t))])
    right = np.concatenate([[0.0], np.cumsum(v_right[:-1] * np.diff(t))])
    gt_t = np.arange(gt_phase, t[-1], 1.0 / gt_rate)
    grid = np.union1d(t, gt_t)
    d_left = np.diff(np.interp(grid, t, left))
    d_right = np.diff(np.interp(grid, t, right))
    x, y, yaw = model.integrate(p, d_left, d_right, np.diff(grid), pose0=(1.0, -2.0, 0.3))
    x = np.concatenate([[1.0], x])
    y = np.concatenate([[-2.0], y])
    yaw = np.concatenate([[0.3], yaw])
    at = np.searchsorted(grid, gt_t)
    return Recording(t, left, right, gt_t, x[at], y[at], np.angle(np.exp(1j * yaw[at])),
                     name=name)


def from_track_speeds(v_left, v_right, icr, rate, gt_rate):
    """
    Record track speeds through a constant-ICR vehicle: encoders at ``rate``, exact truth.

    ``v_left[k]``, ``v_right[k]`` (m/s) are held from sample ``k`` (at ``k / rate`` s) to the
    next; the truth starts at the origin and is taken every ``rate / gt_rate`` samples.

    Returns
    -------
    Recording
        Cumulative travel at the encoder times and the truth of ``ConstantIcr`` with ``icr``.

    """
    t = np.arange(len(v_left)) / rate
    left = np.concatenate([[0.0], np.cumsum(v_left[:-1] / rate)])
    right = np.concatenate([[0.0], np.cumsum(v_right[:-1] / rate)])
    model = ConstantIcr(icr.track_width)
    x, y, yaw = model.integrate(model.from_icr(icr), np.diff(left), np.diff(right), 1.0 / rate)
    pose = np.column_stack([np.r_[0.0, x], np.r_[0.0, y], np.r_[0.0, yaw]])
    every = int(rate / gt_rate)
    gt = pose[::every]
    return Recording(t, left, right, t[::every], gt[:, 0], gt[:, 1], gt[:, 2])


T0_NS = 1_700_000_000_000_000_000
JOINTS = ('left_sprocket_joint', 'right_sprocket_joint')


def write_bag(path, recording, storage='sqlite3', radius=0.1, ground_truth='pose_stamped',
              gt_topic='/mocap/pose', encoder='positions', quantum=0.0, gt_noise=(0.0, 0.0),
              seed=0):
    """
    Write a recording as a bag: /joint_states and the ground truth, stamped in the header.

    Parameters
    ----------
    ground_truth : {'pose_stamped', 'pose_with_covariance', 'odometry', 'tf'}
        Message type of the ground truth (tf: map -> base_link on /tf).
    encoder : {'positions', 'velocities', 'speeds', 'ticks'}
        JointState positions or velocities, or per-side Float64 track speeds
        (/left_track/speed) or Int32 tick counters (/left_track/ticks, 4096 per rev).
    quantum : float
        Joint angle quantisation, rad (0: none).
    gt_noise : tuple of float
        Standard deviations of the ground-truth position (m) and heading (rad).

    """
    from tracked_kinematics.offline.bags.writer import BagWriter
    rng = np.random.default_rng(seed)
    rec = recording
    pos_l, pos_r = rec.left / radius, rec.right / radius
    if quantum:
        pos_l, pos_r = np.round(pos_l / quantum) * quantum, np.round(pos_r / quantum) * quantum
    vel_l = np.gradient(rec.left, rec.enc_t) / radius
    vel_r = np.gradient(rec.right, rec.enc_t) / radius
    noise_p, noise_h = gt_noise
    gx = rec.gt_x + rng.normal(0.0, noise_p, len(rec.gt_t)) if noise_p else rec.gt_x
    gy = rec.gt_y + rng.normal(0.0, noise_p, len(rec.gt_t)) if noise_p else rec.gt_y
    gyaw = rec.gt_yaw + rng.normal(0.0, noise_h, len(rec.gt_t)) if noise_h else rec.gt_yaw
    events = [(int(T0_NS + round(t * 1e9)), 0, k) for k, t in enumerate(rec.enc_t)]
    events += [(int(T0_NS + round(t * 1e9)), 1, k) for k, t in enumerate(rec.gt_t)]
    events.sort()
    ticks = 4096 / (2 * np.pi)
    with BagWriter(path, storage) as bag:
        for stamp, kind, k in events:
            if kind == 0:
                if encoder == 'positions':
                    bag.write('/joint_states', stamp,
                              bag.joint_state(stamp, JOINTS, [pos_l[k], pos_r[k]]))
                elif encoder == 'velocities':
                    bag.write('/joint_states', stamp,
                              bag.joint_state(stamp, JOINTS, (), [vel_l[k], vel_r[k]]))
                elif encoder == 'speeds':
                    bag.write('/left_track/speed', stamp, bag.float64(vel_l[k] * radius))
                    bag.write('/right_track/speed', stamp, bag.float64(vel_r[k] * radius))
                else:
                    bag.write('/left_track/ticks', stamp, bag.int32(round(pos_l[k] * ticks)))
                    bag.write('/right_track/ticks', stamp, bag.int32(round(pos_r[k] * ticks)))
                continue
            x, y, yaw = gx[k], gy[k], gyaw[k]
            if ground_truth == 'pose_stamped':
                msg = bag.pose_stamped(stamp, x, y, yaw)
            elif ground_truth == 'pose_with_covariance':
                msg = bag.pose_with_covariance_stamped(stamp, x, y, yaw)
            elif ground_truth == 'odometry':
                msg = bag.odometry(stamp, x, y, yaw)
            else:
                msg = bag.tf_message(stamp, 'map', 'base_link', x, y, yaw)
            bag.write(gt_topic if ground_truth != 'tf' else '/tf', stamp, msg)
