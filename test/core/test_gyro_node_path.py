"""The node's per-step path through GyroOdometry, its covariance, and Odometry's new terms."""

from helpers.gyro_drive import gyro_drive
import numpy as np
from tracked_kinematics.core.covariance import arc_step, body_jacobian, TrackNoise
from tracked_kinematics.core.gyro import GYRO, GyroConfig, GyroOdometry, replay
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.noise_model import (
    NoiseModel, PRIOR, propagate_body, propagate_step, step_covariance, turn_slip,
    turn_slip_step)
from tracked_kinematics.core.odometry import Odometry

ICR = IcrParams(0.42, 0.353, -0.425, 0.032, 1.0072, 1.0275)
TERMS = NoiseModel(track=0.0, turn=PRIOR.turn, slip=PRIOR.slip, timing=PRIOR.timing, floor=0.0)


def drive(**kwargs):
    return gyro_drive(ICR, **kwargs)


def config(**changes):
    return GyroConfig(**{'imu_delay': 0.05, 'gyro_scale': 1.02, 'adapt': True, **changes})


def test_the_node_path_equals_replay():
    """
    Steps (``update(t, d_l, d_r, dt)``, as odometry_node calls it) give replay's poses.

    odometry_node feeds ``imu(stamp, wz)`` per Imu message and ``update`` per encoder step;
    evaluate_model --fuse-imu calls ``replay`` on the same streams.
    """
    t, left, right, tg, wg = drive()
    poses, sources, end = replay(t, left, right, tg, wg, ICR, config(), terms=TERMS)
    odo = GyroOdometry(ICR, config(), TrackNoise(), TERMS)
    events = sorted([(s, 0, k) for k, s in enumerate(tg)] + [(s, 1, k) for k, s in enumerate(t)])
    got = np.zeros_like(poses)
    last = None
    for stamp, kind, k in events:
        if kind == 0:
            odo.imu(stamp, wg[k])
            continue
        if last is not None:
            assert odo.update(stamp, left[k] - left[last], right[k] - right[last],
                              stamp - t[last])
        got[k] = odo.pose
        last = k
    np.testing.assert_array_equal(got, poses)
    assert sources[-1] == GYRO and end.icr == odo.icr
    assert odo.icr.y_left - odo.icr.y_right > 1.1 * (ICR.y_left - ICR.y_right)  # adapted


def test_covariance_is_psd_grows_with_turning_and_reset_zeroes():
    t, left, right, tg, wg = drive()
    odo = GyroOdometry(ICR, config(), TrackNoise(), TERMS)
    events = sorted([(s, 0, k) for k, s in enumerate(tg)] + [(s, 1, k) for k, s in enumerate(t)])
    last, traces = None, []
    for stamp, kind, k in events:
        if kind == 0:
            odo.imu(stamp, wg[k])
            continue
        if last is not None:
            odo.update(stamp, left[k] - left[last], right[k] - right[last], stamp - t[last])
            p = np.array(odo.covariance_upper)
            full = p[[0, 1, 2, 1, 3, 4, 2, 4, 5]].reshape(3, 3)
            assert np.all(np.isfinite(full)) and np.linalg.eigvalsh(full).min() > -1e-12
            traces.append(full[0, 0] + full[1, 1])
            odo.take_twist()
            tw = np.array(odo.twist_covariance)[[0, 1, 2, 1, 3, 4, 2, 4, 5]].reshape(3, 3)
            assert np.linalg.eigvalsh(tw).min() > -1e-12
        last = k
    assert odo.source == GYRO
    assert np.all(np.diff(traces) >= -1e-15) and traces[-1] > 0.01
    # The heading's variance is the gyro's: far below the encoders' turn term.
    enc = Odometry(ICR, TrackNoise(), TERMS)
    for k in range(1, len(t)):
        enc.update(left[k] - left[k - 1], right[k] - right[k - 1], t[k] - t[k - 1])
    assert odo.covariance_upper[5] < 0.2 * enc.covariance_upper[5]
    odo.reset()
    assert odo.covariance_upper == (0.0,) * 6 and odo.pose == (0.0, 0.0, 0.0)


def test_gyro_heading_variance_grows_with_the_gyro_noise():
    # Pure spin at 0.5 rad/s, the gyro healthy and its bias known: per second the heading's
    # variance grows by about gyro_noise^2 (the model's far larger variance is not used).
    noise = 0.003
    odo = GyroOdometry(ICR, GyroConfig(gyro_noise=noise, measure_noise=False, scale_std=0.0))
    w = 0.5
    spread = ICR.y_left - ICR.y_right
    v = 0.5 * w * spread / ICR.scale_right
    for k in range(1, 4001):       # 0.01 s gyro samples, still 2.5 s, then 10 s spinning
        s = k * 0.0025
        spinning = s > 3.0
        odo.imu(s, w if spinning else 0.0)
        if k % 4 == 0:
            d = v * 0.01 if spinning else 0.0
            odo.update(s, -d, d * ICR.scale_right / ICR.scale_left, 0.01)
    assert odo.source == GYRO
    seconds = 10.0 - 3.0
    # The fused variance: at most the gyro's (a Kalman update of the model's, far larger):
    # its white noise, and its bias's uncertainty, common to every step (issue 35).
    white = noise ** 2 * seconds
    assert 0.7 * white < odo.covariance_upper[5] <= white + (odo.bias_std * seconds) ** 2
    assert odo.covariance_upper[5] > 1.2 * white     # the bias's share is in it


def test_turn_slip_terms_are_the_noise_models():
    """turn_slip_step(turn_slip(...)) is the turn and slip part of propagate_step."""
    body = body_jacobian(ICR)
    model = NoiseModel(track=0.0, turn=3e-3, slip=5e-2, timing=0.0, floor=0.0)
    for d_left, d_right in ((0.01, 0.03), (-0.02, 0.02), (0.05, 0.05), (0.0, 0.0)):
        dx = body[0][0] * d_left + body[0][1] * d_right
        dy = body[1][0] * d_left + body[1][1] * d_right
        dth = body[2][0] * d_left + body[2][1] * d_right
        _, _, m = arc_step(0.7, dx, dy, dth)
        expected = propagate_step((0.0,) * 6, 0.0, 0.0, m,
                                  step_covariance(model, body, ICR.track_width, d_left, d_right))
        got = turn_slip_step((0.0,) * 6, *turn_slip(model, ICR.track_width, dx, dth), m)
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-18)


def upper(q):
    return tuple(q[i, j] for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)))


def test_propagate_step_unrolled_equals_the_matrix_form():
    rng = np.random.default_rng(3)
    for _ in range(20):
        a = rng.standard_normal((3, 3))
        p = a @ a.T
        b = rng.standard_normal((3, 3))
        s = b @ b.T
        m = tuple(tuple(row) for row in rng.standard_normal((2, 3)).tolist())
        dx, dy = rng.standard_normal(2)
        np.testing.assert_allclose(propagate_step(upper(p), dx, dy, m, upper(s)),
                                   upper(propagate_body(p, dx, dy, m, s)), rtol=1e-12,
                                   atol=1e-12)


def test_odometry_without_terms_is_unchanged_and_terms_add():
    steps = [(0.01, 0.012), (-0.01, 0.01), (0.02, 0.02)] * 20
    plain = Odometry(ICR, TrackNoise())
    zero = Odometry(ICR, TrackNoise(), NoiseModel(track=0.0, turn=0.0, slip=0.0, floor=0.0))
    with_terms = Odometry(ICR, TrackNoise(), TERMS)
    for d_left, d_right in steps:
        for odo in (plain, zero, with_terms):
            odo.update(d_left, d_right, 0.02)
    assert zero.pose == plain.pose and zero.covariance_upper == plain.covariance_upper
    assert with_terms.pose == plain.pose
    assert with_terms.covariance_upper[0] > plain.covariance_upper[0]
    assert with_terms.covariance_upper[5] > plain.covariance_upper[5]
    twist, cov = plain.take_twist()
    assert zero.take_twist() == (twist, cov)
    twist_terms, cov_terms = with_terms.take_twist()
    assert twist_terms == twist
    assert cov_terms[0] > cov[0] and cov_terms[3] > cov[3] and cov_terms[5] > cov[5]
