"""Gyro-aided odometry (issue 29): simulated gyros of known faults, and the Warthog runs."""

from dataclasses import replace
import math

from helpers import realdata
import numpy as np
import pytest
from tracked_kinematics.core import evaluate as ev
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.gyro import (
    ENCODERS, fit_gyro_scale, GYRO, GyroConfig, GyroOdometry, replay)
from tracked_kinematics.core.integration import integrate_twist
from tracked_kinematics.core.kinematics import forward, IcrParams
from tracked_kinematics.core.odometry import Odometry
from tracked_kinematics.core.sim.sensors import gyro_samples, GyroModel

WIDTH = 1.0
TRUE = IcrParams(WIDTH, 0.8, -0.8, 0.0, 1.0, 1.0)      # the ground: chi 0.625
MODEL = IcrParams(WIDTH, 0.65, -0.65, 0.0, 1.0, 1.0)   # the terrain file: chi 0.77
RATE = 50.0                                             # encoder samples per second


def drive(seconds=120.0, still=5.0, seed=0):
    """Return a run: still, then turns of varying radius; truth, encoders at RATE."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / RATE)
    # Piecewise-constant commands, 3 s each, after the standstill.
    k = np.floor((t - still) / 3.0).astype(int)
    vs = rng.uniform(0.3, 1.0, k.max() + 2)
    ws = rng.uniform(-0.6, 0.6, k.max() + 2)
    moving = t >= still
    v = np.where(moving, vs[np.maximum(k, 0)], 0.0)
    w = np.where(moving, ws[np.maximum(k, 0)], 0.0)
    v_left = v - TRUE.y_left * w
    v_right = v - TRUE.y_right * w
    v_x, v_y, w_true = forward(v_left, v_right, TRUE)
    dt = np.diff(t)
    x, y, theta = integrate_twist(v_x[:-1], v_y[:-1], w_true[:-1], dt)
    left = np.r_[0.0, np.cumsum(v_left[:-1] * dt)]
    right = np.r_[0.0, np.cumsum(v_right[:-1] * dt)]
    return t, left, right, w_true, np.r_[0.0, theta]


def gyro(t, w_true, seed=1, **faults):
    """Gyro readings of the package's simulator (core/sim/sensors.py)."""
    return gyro_samples(t, w_true[:-1], GyroModel(rate=100.0, **faults),
                        np.random.default_rng(seed))


FAULTS = {'bias': 0.02, 'noise_std': 0.005, 'latency': 0.08, 'scale': 1.04}
KNOWN = GyroConfig(imu_delay=0.08, gyro_scale=1.04, gyro_noise=0.005 / math.sqrt(100.0))


def test_heading_recovered_from_a_biased_scaled_late_gyro():
    t, left, right, w_true, heading = drive(still=10.0)
    g_t, g_w = gyro(t, w_true, **FAULTS)

    def rms(config, g_t=g_t):
        poses, sources, odo = replay(t, left, right, g_t, g_w if len(g_t) else [], MODEL,
                                     config)
        return float(np.sqrt(np.mean((poses[:, 2] - heading) ** 2))), sources, odo

    error, sources, odo = rms(KNOWN)
    assert rms(KNOWN, g_t=np.zeros(0))[0] > 0.5         # the model's slip is wrong
    assert error < 0.025
    assert abs(odo.bias - FAULTS['bias']) < 0.001
    assert np.mean(sources[t > 3.0] == GYRO) > 0.99     # 2 s still: the bias is known
    # Each of the delay and the scale counts (the bias is found in motion too: issue 35).
    for worse in (replace(KNOWN, imu_delay=0.0), replace(KNOWN, gyro_scale=1.0)):
        assert rms(worse)[0] > 1.5 * error, worse


def test_bias_tracked_at_standstill_and_the_heading_holds():
    t = np.arange(0.0, 20.0, 1.0 / RATE)
    zeros = np.zeros_like(t)
    g_t, g_w = gyro(t, zeros, bias=-0.03, noise_std=0.01)
    poses, sources, odo = replay(t, zeros, zeros, g_t, g_w, MODEL,
                                 GyroConfig(gyro_noise=0.01))
    assert abs(odo.bias + 0.03) < 0.002
    assert np.max(np.abs(poses[:, 2])) < 1e-9             # standing still: no drift
    assert sources[-1] == GYRO


@pytest.mark.parametrize('model', [TRUE, MODEL], ids=['right-model', 'wrong-slip'])
def test_a_robot_that_never_stands_still_is_not_misled_by_the_bias(model):
    """The trap of issue 29 (a biased gyro, no standstill): the bias is fitted in motion."""
    t, left, right, w_true, heading = drive(still=0.0)
    g_t, g_w = gyro(t, w_true, bias=0.015, noise_std=0.005, latency=0.08, scale=1.04)
    poses, sources, odo = replay(t, left, right, g_t, g_w, model, KNOWN)
    encoders, _, _ = replay(t, left, right, [], [], model, KNOWN)

    def window_error(p, seconds=10.0):
        # Mean error of the heading change over windows, as evaluate_model scores.
        k = int(seconds * RATE)
        return float(np.mean(np.abs((p[k:, 2] - p[:-k, 2]) - (heading[k:] - heading[:-k]))))

    assert sources[-1] == GYRO
    if model is TRUE:
        # The encoders are exact here: the gyro may not make them worse.
        assert odo.bias == pytest.approx(0.015, abs=0.001)
        assert window_error(poses) < 0.01
    else:
        # Bias and slip fitted together: the gyro waits until its bias is known.
        assert odo.bias == pytest.approx(0.015, abs=0.002)
        assert window_error(poses) <= window_error(encoders)


@pytest.mark.parametrize('fault', ['nan', 'stale', 'saturated', 'jump'])
def test_fallback_without_a_jump_and_back(fault):
    t, left, right, w_true, heading = drive(seconds=40.0)
    g_t, g_w = gyro(t, w_true, **FAULTS)
    config = replace(KNOWN, saturation=3.0, max_jump=1.0, timeout=0.3)
    bad = (g_t >= 20.5) & (g_t < 22.0)
    if fault == 'nan':
        g_w = np.where(bad, np.nan, g_w)
    elif fault == 'saturated':
        g_w = np.where(bad, 3.0, g_w)
    elif fault == 'jump':
        g_w = np.where(np.abs(g_t - 20.5) < 0.005, g_w + 2.0, g_w)
    else:
        g_t, g_w = g_t[~bad], g_w[~bad]
    odo = GyroOdometry(MODEL, config)
    events = sorted([(s, 0, w) for s, w in zip(g_t, g_w)]
                    + [(s, 1, k) for k, s in enumerate(t)])
    steps, sources, at = [], [], []
    for stamp, kind, value in events:
        if kind == 0:
            odo.imu(stamp, value)
            continue
        before = odo.pose
        if odo.encoders(stamp, left[value], right[value]) is None:
            continue
        steps.append([a - b for a, b in zip(odo.pose, before)])
        sources.append(odo.source)
        at.append(stamp)
    steps, sources, at = np.asarray(steps), np.asarray(sources), np.asarray(at)
    switched = np.flatnonzero((sources[1:] == ENCODERS) & (sources[:-1] == GYRO))
    assert len(switched) == 1
    when = at[switched[0] + 1]
    # At once: within the first encoder step after the fault (stale: after the timeout).
    limit = 20.5 + (config.timeout + 2 / RATE if fault == 'stale' else 2 / RATE)
    assert 20.5 - config.imu_delay <= when <= limit
    # No jump: around the fault and the return (no change of command between 20 s and
    # 23 s; the late gyro has caught up with the change at 20 s), every step turns and
    # moves as the robot did, to a few milliradians / mm.
    k = np.searchsorted(t, at)
    near = (at > 20.3) & (at < 22.9)
    true_turn = heading[k] - heading[k - 1]
    assert np.max(np.abs(steps[near, 2] - true_turn[near])) < 0.003
    speed = np.hypot(steps[:, 0], steps[:, 1]) * RATE
    assert np.max(speed[near]) < 1.7
    # Back to the gyro after the recovery time, and the heading stays good.
    back = at[(sources == GYRO) & (at > when)]
    assert len(back) and back[0] < 22.0 + config.recover_time + 0.1
    assert odo.switches == 3                  # to the gyro at the start, away, back
    assert odo.reason == ''


def test_adaptation_converges_to_the_true_spread():
    t, left, right, w_true, heading = drive(seconds=240.0)
    g_t, g_w = gyro(t, w_true, **FAULTS)
    config = replace(KNOWN, adapt=True, adapt_turn=30.0)
    _, _, odo = replay(t, left, right, g_t, g_w, MODEL, config)
    spread = odo.icr.y_left - odo.icr.y_right
    assert spread == pytest.approx(TRUE.y_left - TRUE.y_right, rel=0.03)
    # Adapted ICRs keep the model's offset and scales; bounded by chi <= 1.
    assert odo.icr.y_left + odo.icr.y_right == pytest.approx(0.0, abs=1e-12)
    assert odo.icr.chi <= 1.0
    # Without adaptation the spread stays the model's.
    _, _, fixed = replay(t, left, right, g_t, g_w, MODEL, KNOWN)
    assert fixed.icr == MODEL


def test_adapted_spread_carries_the_fallback():
    """When the gyro is lost after adapting, the encoders' heading uses today's slip."""
    t, left, right, w_true, heading = drive(seconds=240.0)
    g_t, g_w = gyro(t, w_true, **FAULTS)
    keep = g_t < 180.0
    errors = {}
    for adapt in (False, True):
        poses, sources, _ = replay(t, left, right, g_t[keep], g_w[keep], MODEL,
                                   replace(KNOWN, adapt=adapt))
        assert sources[-1] == ENCODERS
        k = np.searchsorted(t, 181.0)
        errors[adapt] = abs((poses[-1, 2] - poses[k, 2]) - (heading[-1] - heading[k]))
    assert errors[True] < 0.3 * errors[False]


def test_gyro_scale_fitted_against_a_pose():
    t, left, right, w_true, heading = drive(seconds=120.0)
    g_t, g_w = gyro(t, w_true, bias=0.01, noise_std=0.005, latency=0.05, scale=0.97)
    scale, std = fit_gyro_scale([g_t], [g_w], [t], [heading], 0.05)
    assert scale == pytest.approx(0.97, abs=0.003)
    assert 0.0 < std < 0.003


def test_without_a_gyro_it_is_the_encoder_odometry():
    """No gyro: the same poses as core.odometry.Odometry, step for step."""
    t, left, right, _, _ = drive(seconds=30.0)
    model = replace(MODEL, x=0.1, y_left=0.7, scale_left=0.97, scale_right=1.02)
    odo, reference = GyroOdometry(model), Odometry(model)
    for k in range(1, len(t)):
        dt = t[k] - t[k - 1]
        assert odo.update(t[k], left[k] - left[k - 1], right[k] - right[k - 1], dt)
        reference.update(left[k] - left[k - 1], right[k] - right[k - 1], dt)
        assert odo.pose == pytest.approx(reference.pose, abs=1e-9)
    assert odo.take_twist()[0] == pytest.approx(reference.take_twist()[0], abs=1e-9)
    assert odo.take_twist()[0] == (0.0, 0.0, 0.0)
    assert not odo.update(t[-1] + 1.0, math.nan, 0.0, 0.1)
    assert not odo.update(t[-1] + 1.0, 0.0, 0.0, 0.0)


def test_reset_keeps_what_was_learnt():
    t, left, right, w_true, _ = drive(seconds=60.0)
    g_t, g_w = gyro(t, w_true, **FAULTS)
    _, _, odo = replay(t, left, right, g_t, g_w, MODEL, replace(KNOWN, adapt=True))
    bias, icr = odo.bias, odo.icr
    odo.reset()
    assert odo.pose == (0.0, 0.0, 0.0) and odo.heading_variance == 0.0
    assert odo.bias == bias and odo.icr == icr and odo.source == GYRO
    odo.set_model(TRUE)
    assert odo.icr == TRUE


def test_config_checked():
    with pytest.raises(ValueError, match='gyro_scale'):
        GyroConfig(gyro_scale=0.0)
    with pytest.raises(ValueError, match='adapt'):
        GyroConfig(adapt=1)


WARTHOG = ('warthog_grass_2024-07-18_16h59', 'warthog_grass_2024-07-29_14h04',
           'warthog_grass_2024-08-08_16h11')


def test_warthog_gyro_aided_beats_the_encoders_after_10_s():
    """Fit on two Warthog grass runs, score the third as evaluate_model does."""
    from tracked_kinematics.offline.bags import EncoderSource, GroundTruthSource, read_recording
    paths = [realdata.bag(name) for name in WARTHOG]
    refs = [read_recording(p, EncoderSource(sprocket_radius=0.3), imu_topic='/imu/data',
                           ground_truth=GroundTruthSource(realdata.TOPIC)) for p in paths]
    recs = [ident.Recording(r.enc_t, r.left, r.right, *r.pose, name=r.name) for r in refs]
    fit = ident.identify(recs[:2], 'icr_scales', 1.08, ground_truth_delay='auto',
                         accept_uncertain=True)
    imu_delay = ident.fit_recordings(refs[:2], 1.08).imu_delay.delay
    assert -0.23 <= imu_delay <= -0.16        # the encoders trail the gyro
    delay, _ = ident.estimate_delays([recs[2]])
    rec = ident.correct_ground_truth([recs[2]], delay.delay)[0]
    pieces = ev.cut(rec, 0, True, 1.08).pieces
    grid = np.union1d(rec.enc_t, rec.gt_t[(rec.gt_t >= rec.enc_t[0])
                                          & (rec.gt_t <= rec.enc_t[-1])])
    poses, sources, _ = replay(grid, np.interp(grid, rec.enc_t, rec.left),
                               np.interp(grid, rec.enc_t, rec.right), refs[2].gyro_t,
                               refs[2].gyro_rate, fit.icr, GyroConfig(imu_delay=imu_delay))
    icr = fit.icr
    params = (icr.y_left, icr.y_right, icr.x, icr.scale_left, icr.scale_right)
    errors = {'encoders': [], 'gyro': []}
    for piece in pieces:
        i, j, _ = ev.moving_windows(piece, 10.0, 0.1)
        errors['encoders'].append(ev.relative_errors(ev.odometry(piece, params),
                                                     piece.truth, i, j)[0])
        errors['gyro'].append(ev.relative_errors(poses[np.searchsorted(grid, piece.t)],
                                                 piece.truth, i, j)[0])
    encoders, aided = (float(np.mean(np.concatenate(errors[k]))) for k in ('encoders', 'gyro'))
    assert np.mean(sources == GYRO) > 0.95
    assert aided < 0.97 * encoders, (aided, encoders)
    assert math.isfinite(aided)
