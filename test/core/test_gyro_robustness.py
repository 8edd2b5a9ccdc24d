"""The gyro-aided odometry against any input (issue 35): each test failed on the old core."""

from dataclasses import replace
import math

import numpy as np
import pytest
from tracked_kinematics.core.gyro import (
    ENCODERS, ERROR, GYRO, GyroConfig, GyroOdometry, OK, replay)
from tracked_kinematics.core.gyro.samples import MAX_SAMPLES
from tracked_kinematics.core.integration import integrate_twist
from tracked_kinematics.core.kinematics import forward, IcrParams
from tracked_kinematics.core.sim.sensors import gyro_samples, GyroModel

TRUE = IcrParams(1.0, 0.8, -0.8, 0.0, 1.0, 1.0)      # the ground: chi 0.625
MODEL = IcrParams(1.0, 0.65, -0.65, 0.0, 1.0, 1.0)   # the terrain file: chi 0.77
RATE = 50.0
NOISE = 0.005                                        # rad/s per sample at 100 Hz
CONFIG = GyroConfig(gyro_noise=NOISE / 10.0)


def run(v, w, t0=0.0):
    """Return a drive of body commands ``v``, ``w`` (per sample at RATE) on the TRUE ground."""
    n = len(v)
    t = t0 + np.arange(n) / RATE
    v_left = v - TRUE.y_left * w
    v_right = v - TRUE.y_right * w
    _, _, w_true = forward(v_left, v_right, TRUE)
    dt = np.diff(t)
    _, _, theta = integrate_twist(*forward(v_left[:-1], v_right[:-1], TRUE), dt)
    left = np.r_[0.0, np.cumsum(v_left[:-1] * dt)]
    right = np.r_[0.0, np.cumsum(v_right[:-1] * dt)]
    return t, left, right, w_true, np.r_[0.0, theta]


def turns(seconds, still=3.0, seed=0, t0=0.0, curvature_sign=None):
    """Return a drive: still, then piecewise-constant arcs, 3 s each, of both signs."""
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE)
    k = np.maximum(np.floor((np.arange(n) / RATE - still) / 3.0).astype(int), 0)
    vs = rng.uniform(0.3, 1.0, k.max() + 1)
    ws = rng.uniform(-0.6, 0.6, k.max() + 1)
    if curvature_sign is not None:
        ws = curvature_sign * np.abs(ws).clip(0.2)
    moving = np.arange(n) / RATE >= still
    return run(np.where(moving, vs[k], 0.0), np.where(moving, ws[k], 0.0), t0)


def readings(t, w_true, seed=1, **faults):
    model = GyroModel(rate=100.0, **{'noise_std': NOISE, **faults})
    return gyro_samples(t, w_true[:-1], model, np.random.default_rng(seed))


def feed(odo, t, left, right, g_t, g_w, offset=(0.0, 0.0)):
    """Feed both streams in stamp order; return the headings after each encoder sample."""
    events = sorted([(s, 0, k) for k, s in enumerate(g_t)]
                    + [(s, 1, k) for k, s in enumerate(t)])
    headings = []
    for s, kind, k in events:
        if kind == 0:
            odo.imu(s, g_w[k])
        else:
            odo.encoders(s, offset[0] + left[k], offset[1] + right[k])
            headings.append(odo.pose[2])
    return np.array(headings)


def test_stamps_going_back_restart_the_gyro_and_keep_the_pose():
    # Before: TypeError in _gyro_increment (None - float): the node died.
    t, left, right, w_true, heading = turns(30.0)
    g_t, g_w = readings(t, w_true)
    odo = GyroOdometry(MODEL, CONFIG)
    feed(odo, t, left, right, g_t, g_w)
    assert odo.source == GYRO
    kept = odo.pose
    # The same drive again, stamped 100 s earlier (a bag played in a loop, a sim reset).
    h = feed(odo, t - 100.0, left, right, g_t - 100.0, g_w, (left[-1], right[-1]))
    assert all(map(math.isfinite, odo.pose))
    assert h[0] == pytest.approx(kept[2])                 # the pose carries on
    turned = h[-1] - h[0]
    assert turned == pytest.approx(heading[-1] - heading[0], abs=0.05)
    assert odo.source == GYRO


@pytest.mark.parametrize('value', [1e20, 1e155, 1e200, math.nan, math.inf, -1e308])
@pytest.mark.parametrize('gates', ['on', 'off'])
def test_one_garbage_sample_neither_kills_nor_freezes_the_heading(value, gates):
    # Before: 1e155 raised OverflowError; 1e20 froze the cumulative integral for good.
    config = CONFIG if gates == 'on' else replace(CONFIG, saturation=math.inf,
                                                  max_jump=math.inf)
    t, left, right, w_true, heading = turns(60.0)
    g_t, g_w = readings(t, w_true)
    g_w = g_w.copy()
    g_w[np.searchsorted(g_t, 20.0)] = value
    odo = GyroOdometry(MODEL, config)
    h = feed(odo, t, left, right, g_t, g_w)
    assert np.all(np.isfinite(h)) and all(map(math.isfinite, odo.covariance_upper))
    assert np.all(np.isfinite(odo.publish()[1]))
    # A clean drive afterwards turns right: the last 30 s within 0.05 rad of the truth.
    after = t >= 30.0
    turned = h[after][-1] - h[after][0]
    assert turned == pytest.approx(heading[after][-1] - heading[after][0], abs=0.05)
    assert odo.source == GYRO and odo.level == OK
    assert MODEL.chi <= odo.icr.chi * 1.0001 or odo.icr.chi > 0.2


def test_a_sample_from_the_far_future_does_not_turn_the_gyro_off():
    t, left, right, w_true, heading = turns(40.0)
    g_t, g_w = readings(t, w_true)
    g_t = g_t.copy()
    g_t[np.searchsorted(g_t, 15.0)] = 2.1e9           # 2038
    odo = GyroOdometry(MODEL, CONFIG)
    h = feed(odo, t, left, right, g_t, g_w)
    assert odo.source == GYRO
    after = t >= 20.0
    assert h[after][-1] - h[after][0] == pytest.approx(
        heading[after][-1] - heading[after][0], abs=0.05)


def test_buffers_stay_bounded_whatever_the_clocks_do():
    odo = GyroOdometry(MODEL, CONFIG)
    odo.encoders(0.0, 0.0, 0.0)
    for k in range(3 * MAX_SAMPLES):          # the encoders silent, the gyro at 400 Hz
        odo.imu(k / 400.0, 0.0)
    assert len(odo.samples._samples) <= MAX_SAMPLES


@pytest.mark.parametrize('start, end', [
    (10.0, 20.0),
    # From the node's start or within its first checkpoint, no bias known: before, the
    # turntable's rate was taken as the bias (0.024-0.030 rad/s, 42-67 deg lost a minute
    # later in the node's test); a push of 1 or 2 s.
    (0.0, 10.0), (3.0, 13.0), (2.0, 4.0), (8.0, 9.0)])
def test_a_turntable_at_standstill_is_not_learnt_as_bias(start, end):
    # Before: standstill was decided from the encoders alone: 0.02 rad/s for 10 s became a
    # bias of about 0.01 rad/s, 0.6 rad of heading error a minute later.
    still = np.zeros(int(30.0 * RATE))
    v = np.r_[still, np.full(int(60.0 * RATE), 0.8)]
    t, left, right, _, _ = run(v, np.zeros_like(v))
    w_true = np.where((t >= start) & (t < end), 0.02, 0.0)   # the turntable turns
    g_t, g_w = readings(t, w_true, bias=0.004)
    odo = GyroOdometry(MODEL, CONFIG)
    h = feed(odo, t, left, right, g_t, g_w)
    straight = t >= 30.0
    assert abs(h[straight][-1] - h[straight][0]) < math.radians(2.0)   # truth: straight
    assert odo.bias == pytest.approx(0.004, abs=0.001)


def test_a_bias_that_drifts_over_a_long_parking_is_no_turntable():
    # Each standstill block is checked against the 5 s before it, not against all the
    # standstill: a bias warming up by 0.006 rad/s over 3 minutes is followed, never refused.
    t = np.arange(0.0, 180.0, 1.0 / RATE)
    zeros = np.zeros_like(t)
    g_t, g_w = readings(t, zeros)
    g_w = g_w + 0.004 + 0.006 * np.asarray(g_t) / 180.0
    _, _, odo = replay(t, zeros, zeros, g_t, g_w, MODEL, CONFIG)
    assert not odo.filter.still_refused
    # Followed, a minute behind (bias_time): 0.0081 where the bias has reached 0.010.
    assert odo.bias == pytest.approx(0.010, abs=0.0025)


def test_the_noise_density_is_measured_without_the_bias_of_its_block():
    t = np.arange(0.0, 60.0, 1.0 / RATE)
    zeros = np.zeros_like(t)
    g_t, g_w = readings(t, zeros, bias=-0.03, noise_std=0.01)
    _, _, odo = replay(t, zeros, zeros, g_t, g_w, MODEL, GyroConfig(gyro_noise=0.05))
    # White noise of 0.01 rad/s per sample at 100 Hz: a density of 0.001 rad/s/sqrt(Hz).
    assert odo.gyro_noise == pytest.approx(0.001, rel=0.12)


@pytest.mark.parametrize('factor, cause', [(-1.0, 'other way'), (57.3, 'times'),
                                           (0.05, 'another axis')])
def test_a_gyro_that_disagrees_with_the_tracks_is_refused(factor, cause):
    # Before: an upside-down (or NED) IMU mirrored the path, with OK on /diagnostics, and
    # the adaptation drove chi to its bound.
    t, left, right, w_true, _ = turns(60.0)
    g_t, g_w = readings(t, w_true)
    g_w = factor * g_w                       # z down; deg/s; the rate of another axis
    poses, sources, odo = replay(t, left, right, g_t, g_w, MODEL, replace(CONFIG, adapt=True))
    encoders, _, _ = replay(t, left, right, [], [], MODEL, CONFIG)
    assert odo.level == ERROR and cause in odo.reason
    assert np.mean(sources[t > 30.0] == ENCODERS) == 1.0
    # Never fused, never adapted: the encoders' heading, the file's ICRs.
    assert np.abs(poses[:, 2] - encoders[:, 2]).max() < 0.05
    assert odo.icr == MODEL


def test_a_gyro_on_another_clock_is_refused():
    t, left, right, w_true, _ = turns(30.0)
    g_t, g_w = readings(t, w_true)
    odo = GyroOdometry(MODEL, CONFIG)
    # They arrive together; the gyro's stamps are 1000 s ahead.
    events = sorted([(s, 0, k) for k, s in enumerate(g_t)] + [(s, 1, k) for k, s in enumerate(t)])
    sources = []
    for _, kind, k in events:
        if kind == 0:
            odo.imu(g_t[k] + 1000.0, g_w[k])
        else:
            odo.encoders(t[k], left[k], right[k])
            sources.append(odo.source)
    assert odo.level == ERROR and 'clock' in odo.reason
    assert set(sources) == {ENCODERS}


def test_a_gyro_that_goes_silent_is_stale_not_on_another_clock():
    t, left, right, w_true, _ = turns(60.0)
    g_t, g_w = readings(t, w_true)
    keep = (g_t < 20.0) | (g_t > 45.0)                # 25 s without a sample
    odo = GyroOdometry(MODEL, CONFIG)
    levels = []
    events = sorted([(s, 0, k) for k, s in enumerate(g_t[keep])]
                    + [(s, 1, k) for k, s in enumerate(t)])
    for s, kind, k in events:
        if kind == 0:
            odo.imu(s, g_w[keep][k])
        else:
            odo.encoders(s, left[k], right[k])
            levels.append((s, odo.level, odo.reason))
    silent = [(lvl, why) for s, lvl, why in levels if 21.0 < s < 45.0]
    assert {lvl for lvl, _ in silent} == {'warn'} and 'stale' in silent[-1][1]
    assert odo.source == GYRO and odo.level == OK


def test_a_robot_that_never_stops_uses_its_gyro_with_the_bias_it_finds():
    # Before: the bias was never called known in motion (issue 35, item 0).
    t, left, right, w_true, heading = turns(180.0, still=0.0, seed=3)
    g_t, g_w = readings(t, w_true, bias=-0.015)
    poses, sources, odo = replay(t, left, right, g_t, g_w, MODEL, CONFIG)
    encoders, _, _ = replay(t, left, right, [], [], MODEL, CONFIG)
    assert np.mean(sources[t > 30.0] == GYRO) > 0.95
    assert odo.bias == pytest.approx(-0.015, abs=0.003)
    k = int(10.0 * RATE)

    def error(p, truth=heading[t > 30.0]):
        return float(np.mean(np.abs((p[k:, 2] - p[:-k, 2]) - (truth[k:] - truth[:-k]))))

    assert error(poses[t > 30.0]) < 0.5 * error(encoders[t > 30.0])


def test_the_terrain_files_bias_is_used_at_once():
    t, left, right, w_true, heading = turns(30.0, still=0.0, seed=4)
    g_t, g_w = readings(t, w_true, bias=-0.015)
    config = replace(CONFIG, gyro_bias=-0.015, gyro_bias_sigma=0.001)
    _, sources, _ = replay(t, left, right, g_t, g_w, MODEL, config)
    assert np.mean(sources[t > 3.0] == GYRO) > 0.95


def test_one_sided_curvature_from_the_start_does_not_make_the_bias_known():
    # Slip and bias are collinear there: the bias is not known, the heading the encoders'.
    t, left, right, w_true, _ = run(np.full(int(40 * RATE), 0.6), np.full(int(40 * RATE), 0.3))
    g_t, g_w = readings(t, w_true, bias=0.01)
    _, sources, odo = replay(t, left, right, g_t, g_w, MODEL, CONFIG)
    assert np.all(sources == ENCODERS)
    assert not odo.bias_known and 'bias is not known' in odo.reason


def test_adaptation_remembers_per_radian_and_returns_to_the_file_when_off():
    # Before: the RLS forgot per second of motion: chi decayed back on straights.
    t1, l1, r1, w1, _ = turns(90.0, seed=5)
    v = np.full(int(240 * RATE), 0.8)
    t2, l2, r2, w2, _ = run(v, np.zeros_like(v), t0=t1[-1] + 1.0 / RATE)
    g1 = readings(t1, w1)
    g2 = readings(t2, w2, seed=2)
    odo = GyroOdometry(MODEL, replace(CONFIG, adapt=True))
    feed(odo, t1, l1, r1, *g1)
    adapted = odo.icr.chi
    assert adapted == pytest.approx(TRUE.chi, abs=0.03)
    feed(odo, t2, l2, r2, *g2, offset=(l1[-1], r1[-1]))
    assert odo.icr.chi == pytest.approx(adapted, abs=0.01)   # four minutes straight
    odo.config = replace(odo.config, adapt=False)
    odo.step(t2[-1] + 0.02, 0.016, 0.016, 0.02)
    assert odo.icr == MODEL


@pytest.mark.parametrize('name, value', [('adapt_prior', 0.0), ('adapt_turn', 0.0),
                                         ('gyro_bias_sigma', -1.0), ('bias_horizon', math.nan),
                                         ('imu_delay', 1e3)])
def test_the_configs_own_limits_are_checked(name, value):
    # Before: GyroConfig(adapt_prior=0) divided by zero at the first segment.
    with pytest.raises(ValueError, match=name):
        GyroConfig(**{name: value})


@pytest.mark.parametrize('wild, offset', [
    ('one', 4.0), ('one', -3.0), ('one', -7.0), ('second_publisher', 3.0),
    ('second_publisher', -7.0)])
def test_wild_stamps_neither_restart_nor_shut_out_the_gyro(wild, offset):
    # Before: one sample stamped 4 s ahead (within the node's 10-s clock window) shut out
    # every later sample for 4 s as out of order, /diagnostics OK; one 7 s back restarted
    # the gyro twice; a second publisher 3 s ahead owned the buffer (its samples used 3 s
    # early, the true ones dropped).
    t, left, right, w_true, heading = turns(30.0)
    g_t, g_w = readings(t, w_true)
    stamps, g_w = g_t.copy(), g_w.copy()
    at = np.searchsorted(g_t, 12.0)
    wild_ones = [at] if wild == 'one' else slice(at, None, 2)
    stamps[wild_ones] += offset
    if wild != 'one':
        g_w[wild_ones] = 1.0    # the other publisher reads something else
    # Fed as they arrive (at the true times), stamped as they are.
    events = sorted([(s, 0, k) for k, s in enumerate(g_t)]
                    + [(s, 1, k) for k, s in enumerate(t)])
    odo = GyroOdometry(MODEL, CONFIG)
    h, sources = [], []
    for _, kind, k in events:
        if kind == 0:
            odo.imu(stamps[k], g_w[k])
        else:
            odo.encoders(t[k], left[k], right[k])
            h.append(odo.pose[2])
            sources.append(odo.source)
    # The gyro in use throughout once it was: no restart, nothing shut out.
    first = sources.index(GYRO)
    assert set(sources[first:]) == {GYRO}
    # Each wild sample dropped (but the last, held: nothing came after it yet).
    assert odo.samples.dropped == (1 if wild == 'one' else len(g_t[wild_ones]) - 1)
    after = t >= 12.0
    h = np.array(h)
    assert h[after][-1] - h[after][0] == pytest.approx(
        heading[after][-1] - heading[after][0], abs=0.03)


@pytest.mark.parametrize('offset', [-3.0, -1.0, 1.0, 2.0, 4.5])
def test_a_gyro_on_a_clock_seconds_off_is_refused_naming_the_clock(offset):
    # Before: within the 5-s clock limit, a gyro 1-4.5 s ahead was fused (1 s: heading error
    # 0.29 rad where the encoders alone had 0.14) or refused as 'on another axis' /
    # 'upside down'; one 1-3 s behind was never used, with OK ('the gyro restarts').
    t, left, right, w_true, heading = turns(30.0)
    g_t, g_w = readings(t, w_true)
    odo = GyroOdometry(MODEL, CONFIG)
    encoders_alone = GyroOdometry(MODEL, CONFIG)
    # As they arrive (at the true times), stamped on the IMU's clock.
    events = sorted([(s, 0, k) for k, s in enumerate(g_t)]
                    + [(s, 1, k) for k, s in enumerate(t)])
    for _, kind, k in events:
        if kind == 0:
            odo.imu(g_t[k] + offset, g_w[k])
        else:
            odo.encoders(t[k], left[k], right[k])
    h = feed(encoders_alone, t, left, right, (), ())
    assert odo.source == ENCODERS and odo.level == ERROR
    assert odo.reason.startswith(f"the gyro's stamps are {offset:+.2g}")
    assert 'another clock' in odo.reason
    assert odo.pose[2] == pytest.approx(h[-1], abs=1e-9)


def test_samples_ahead_of_an_encoder_backlog_are_no_clock():
    # An executor busy for 3 s: the encoders' messages of those seconds come late, at once,
    # after the gyro's (taken as they arrived): the gyro is then seconds ahead of each step
    # while the backlog clears, which is no clock.
    t, left, right, w_true, heading = turns(30.0)
    g_t, g_w = readings(t, w_true)
    odo = GyroOdometry(MODEL, CONFIG)
    stall = (t >= 15.0) & (t < 18.0)
    events = sorted([(s, 0, k) for k, s in enumerate(g_t)]
                    + [(18.0 if stall[k] else s, 1, k) for k, s in enumerate(t)])
    levels = []
    for _, kind, k in events:
        if kind == 0:
            odo.imu(g_t[k], g_w[k])
        else:
            odo.encoders(t[k], left[k], right[k])
            levels.append(odo.level)
    assert ERROR not in levels and odo.source == GYRO
    assert odo.pose[2] == pytest.approx(heading[-1], abs=0.05)
