"""
The bias found in motion where the tracks slip far more than configured (issue 35, item 4).

On the Warthog on ice the in-motion fit took its first segments at the configured slip
error, far below the real one, and called the bias known from them (-0.19 rad/s +- 0.02
where the gyro's mean rate was the tracks' within 0.001); the later segments, taken with the
variance factor grown by then, weighed too little to move it; and the fusion weighed the
gyro against the configured error, not the terrain file's: the source said gyro, the
heading was the encoders'.
"""

import numpy as np
import pytest
from tracked_kinematics.core.gyro import GYRO, GyroConfig, replay
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.noise_model import NoiseModel
from tracked_kinematics.core.sim.sensors import gyro_samples, GyroModel

MODEL = IcrParams(1.0, 0.65, -0.65, 0.0, 1.0, 1.0)
RATE = 50.0
CONFIG = GyroConfig(gyro_noise=0.0005)
SPEED = 1.0
VEER = 0.01
#: rad^2/rad: the terrain file's turn term (identify_icr fits 0.133 on the Warthog on ice),
#: which the drive's slip follows: 25 times the configured 10 % error over a 1-s turn of
#: 0.2 rad.
TERMS = NoiseModel(turn=0.25)


def slipping_drive(seconds=240.0, seed=0):
    """
    Return a drive at constant speed whose yaw is the model's plus a veer and a random slip.

    The model turns at piecewise-constant rates (3 s each, mostly right: the turn and the
    duration nearly collinear, the duration and the distance exactly); the true yaw rate
    adds VEER rad/m (a heading per metre the tracks miss) and a slip rate drawn every
    second, of the variance the file's turn term gives the turn made in it. The gyro has no
    bias.
    """
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE)
    t = np.arange(n) / RATE
    w_model = rng.uniform(-0.5, 0.1, n // int(3 * RATE) + 1)[(t // 3.0).astype(int)]
    # The slip: per second, the file's turn term's variance for the turn made in it.
    w_slip = rng.normal(0.0, 1.0, n // int(RATE) + 1)[t.astype(int)] * np.sqrt(
        TERMS.turn * np.abs(w_model))
    v_left = SPEED - MODEL.y_left * w_model
    v_right = SPEED - MODEL.y_right * w_model
    dt = np.diff(t)
    left = np.r_[0.0, np.cumsum(v_left[:-1] * dt)]
    right = np.r_[0.0, np.cumsum(v_right[:-1] * dt)]
    w_true = w_model + VEER * SPEED + w_slip
    heading = np.r_[0.0, np.cumsum(w_true[:-1] * dt)]
    g_t, g_w = gyro_samples(t, w_true[:-1], GyroModel(rate=100.0, noise_std=0.005),
                            np.random.default_rng(seed + 1))
    return t, left, right, heading, g_t, g_w


@pytest.mark.parametrize('seed', [0, 1, 4])
def test_a_slipping_constant_speed_drive_does_not_make_a_wrong_bias_known(seed):
    # Before: the fused heading's error over 10 s was 0.95-0.97 times the encoders' (the
    # gyro weighed against the configured error), and with seed 4 the bias was called known
    # 5.7 standard deviations from the truth. Measured now (seeds 0-7): within 1.2 standard
    # deviations, the heading error 0.13-0.61 times the encoders'.
    t, left, right, heading, g_t, g_w = slipping_drive(seed=seed)
    poses, sources, odo = replay(t, left, right, g_t, g_w, MODEL, CONFIG, terms=TERMS)
    encoders, _, _ = replay(t, left, right, [], [], MODEL, CONFIG, terms=TERMS)
    # Zero bias; at a constant speed the veer passes for one (the two are collinear).
    assert abs(odo.bias - VEER * SPEED) <= 3.0 * odo.bias_std
    # The gyro used, with the uncertainty it has, and its heading taken.
    late = t > 60.0
    assert np.mean(sources[late] == GYRO) > 0.9
    k = int(10.0 * RATE)

    def error(p, truth=heading[late]):
        return float(np.mean(np.abs((p[k:, 2] - p[:-k, 2]) - (truth[k:] - truth[:-k]))))

    assert error(poses[late]) < 0.8 * error(encoders[late])
