"""
The gyro-aided odometry's own noise constants (issue 35, item 6): published, fitted, read.

The ``drift`` term of the published covariance, the gyro-aided constants used only while the
heading is the gyro's, their fit on windows drawn from known constants, and the terrain
file's ``covariance.gyro_aided.*`` keys (a file without them publishes as before).
"""

from dataclasses import replace
import math

import numpy as np
import pytest
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.core.evaluate.gyro_noise import fit_gyro_noise, GYRO_TERMS, GyroWindows
from tracked_kinematics.core.gyro import GyroConfig, replay
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.noise_model import NoiseModel, published_covariance
from tracked_kinematics.params import gyro_noise_model_from_values, noise_model_from_values

ICR = IcrParams(0.6, 0.35, -0.35)


def test_drift_adds_the_squared_displacement_on_both_axes():
    upper = (0.01, 0.0, 0.0, 0.02, 0.0, 0.001)
    pose = (3.0, 4.0, 0.3)
    still = (0.0, 0.0, 0.0)
    got = published_covariance(upper, pose, still, still, NoiseModel(track=0.0, drift=0.01))
    # 0.01 x |p|^2 = 0.01 x 25 on x and y, nothing across or on the heading.
    np.testing.assert_allclose(got, (0.26, 0.0, 0.0, 0.27, 0.0, 0.001), atol=1e-12)
    assert NoiseModel(drift=0.01).beside_the_steps
    with pytest.raises(ValueError, match='drift'):
        NoiseModel(drift=-1.0)


def drive(seconds=30.0, rate=20.0):
    """Return a curve then a straight, the gyro agreeing: (enc_t, left, right, rate)."""
    t = np.arange(0.0, seconds, 1.0 / rate)
    v_l = np.where(t < seconds / 2, 0.3, 0.5)
    v_r = np.where(t < seconds / 2, 0.7, 0.5)
    left = np.concatenate([[0.0], np.cumsum(v_l[1:] / rate)])
    right = np.concatenate([[0.0], np.cumsum(v_r[1:] / rate)])
    w = (v_r - v_l) / 0.7
    return t, left, right, w


def replayed(gyro_terms, with_gyro=True):
    t, left, right, w = drive()
    terms = NoiseModel(track=0.0, slip=0.01, timing=0.001, floor=0.0)
    config = GyroConfig(gyro_bias_sigma=0.001)
    g_t, g_w = (t, w) if with_gyro else (np.zeros(0), np.zeros(0))
    poses, sources, odo = replay(t, left, right, g_t, g_w, ICR, config, terms=terms,
                                 gyro_terms=gyro_terms)
    return poses, sources, odo.published


def test_the_gyro_aided_terms_are_published_while_the_heading_is_the_gyros():
    gyro_terms = NoiseModel(track=0.0, slip=0.05, timing=0.004, floor=0.0, drift=0.002)
    _, sources, mine = replayed(gyro_terms)
    _, _, files = replayed(None)
    assert sources[-1] == 'gyro'
    gyro = sources == 'gyro'
    # Before the gyro is used, the encoders' terms: the same covariance; after, more.
    first = int(np.argmax(gyro))
    assert first > 0
    np.testing.assert_allclose(mine[:first], files[:first], rtol=1e-12, atol=1e-15)
    assert np.all(mine[-1, [0, 3]] > 1.5 * files[-1, [0, 3]])
    # Without a gyro the gyro-aided terms never enter.
    _, _, alone = replayed(gyro_terms, with_gyro=False)
    _, _, alone_files = replayed(None, with_gyro=False)
    np.testing.assert_allclose(alone, alone_files, rtol=1e-12, atol=1e-15)


def windows_from(constants, n=4000, seed=3):
    """Return windows whose errors are drawn from ``fixed + sum c_m A_m``, random shapes."""
    rng = np.random.default_rng(seed)
    fixed = np.zeros((n, 2, 2))
    fixed[:, 0, 0] = fixed[:, 1, 1] = 1e-4
    bases = np.zeros((n, len(GYRO_TERMS), 2, 2))
    turned = rng.uniform(0.0, 3.0, n)          # slip: per radian turned, isotropic
    bases[:, 0, 0, 0] = bases[:, 0, 1, 1] = turned
    rate = rng.normal(0.0, 0.5, (n, 2))       # timing: the rate's outer product
    bases[:, 1] = rate[:, :, None] * rate[:, None, :]
    p2 = rng.uniform(0.0, 25.0, n)            # drift: |p|^2 I
    bases[:, 2, 0, 0] = bases[:, 2, 1, 1] = p2
    length = np.where(np.arange(n) % 2, 5.0, 10.0)
    windows = GyroWindows(np.zeros((n, 2)), fixed, bases, length, 1)
    cov = windows.covariances(constants)
    errors = np.einsum('wij,wj->wi', np.linalg.cholesky(cov), rng.standard_normal((n, 2)))
    return GyroWindows(errors, fixed, bases, length, 1)


def test_the_fit_recovers_the_constants_the_errors_were_drawn_from():
    truth = (0.02, 0.01, 0.001)
    found = fit_gyro_noise(windows_from(truth), NoiseModel(slip=0.002, timing=0.05), dof=None)
    for term, value in zip(GYRO_TERMS, truth):
        assert getattr(found, term) == pytest.approx(value, rel=0.15), term
    # The terms not fitted are the encoders' model's.
    assert found.track == NoiseModel().track


def test_the_fit_refuses_too_few_windows():
    few = windows_from((0.02, 0.01, 0.001), n=20)
    with pytest.raises(ValueError, match='too few gyro-aided windows'):
        fit_gyro_noise(few, NoiseModel())


def test_a_file_without_the_gyro_aided_keys_publishes_as_before():
    values = {'covariance.slip': 0.02, 'covariance.timing': 0.01, 'covariance.scale': 0.001}
    assert gyro_noise_model_from_values(values) == noise_model_from_values(values)
    unset = {**values, 'covariance.gyro_aided.slip': -1.0, 'covariance.gyro_aided.timing': -1.0}
    assert gyro_noise_model_from_values(unset) == noise_model_from_values(values)
    own = gyro_noise_model_from_values({**values, 'covariance.gyro_aided.slip': 0.005,
                                        'covariance.gyro_aided.drift': 0.001})
    assert (own.slip, own.timing, own.drift, own.scale) == (0.005, 0.01, 0.001, 0.001)


@pytest.mark.parametrize('key, value', [('covariance.gyro_aided.slip', -0.5),
                                        ('covariance.gyro_aided.timing', math.nan),
                                        ('covariance.gyro_aided.drift', -1.0),
                                        ('covariance.gyro_aided.slip', True)])
def test_bad_gyro_aided_values_are_refused_by_name(key, value):
    with pytest.raises(InvalidParameters, match=key.replace('.', r'\.')):
        gyro_noise_model_from_values({key: value})


def recording(gyro_sign=1.0, seconds=120.0, rate=20.0):
    """Return a drive of curves, straights and pivots, its pose exact, its gyro ``sign`` x."""
    from tracked_kinematics.core.identify import Recording
    rng = np.random.default_rng(5)
    speeds = []
    while len(speeds) < seconds * rate:
        v = rng.uniform(0.2, 0.6)
        speeds += [rng.choice([(v, v), (0.5 * v, v), (-v, v), (v, -v)])] * int(rate * 4)
    speeds = np.array(speeds[:int(seconds * rate)])
    t = np.arange(len(speeds)) / rate
    d = np.vstack([[0.0, 0.0], speeds[1:] / rate])
    w = (speeds[:, 1] - speeds[:, 0]) / 0.7
    heading = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) / rate)])
    mid = np.concatenate([[0.0], 0.5 * (heading[1:] + heading[:-1])])
    ds = 0.5 * (d[:, 0] + d[:, 1])
    x, y = np.cumsum(ds * np.cos(mid)), np.cumsum(ds * np.sin(mid))
    return Recording(t, np.cumsum(d[:, 0]), np.cumsum(d[:, 1]), t[::2], x[::2], y[::2],
                     heading[::2], gyro_t=t, gyro_rate=gyro_sign * w)


@pytest.mark.parametrize('sign', [1.0, -1.0])
def test_only_windows_that_end_on_the_gyro_are_fitted_on(sign):
    from tracked_kinematics.core.evaluate import cut
    from tracked_kinematics.core.evaluate.gyro_noise import gyro_windows, RESET_OFFSETS
    from tracked_kinematics.core.covariance import TrackNoise
    rec = recording(sign)
    pieces = cut(rec, 0, True, 0.7).pieces
    model = NoiseModel(slip=0.01, timing=0.001)
    windows = gyro_windows([rec], pieces, ICR, GyroConfig(gyro_bias_sigma=0.001),
                           TrackNoise(), model, (5.0, 10.0), 0.1)
    if sign < 0:
        # A gyro turning the other way is refused: the heading is the encoders', nothing to
        # fit the gyro-aided constants on.
        assert len(windows) == 0
        with pytest.raises(ValueError, match='too few'):
            fit_gyro_noise(windows, model)
        return
    assert len(windows) >= len(RESET_OFFSETS) * (20 + 10)
    assert windows.bases.shape == (len(windows), len(GYRO_TERMS), 2, 2)
    # The drift basis is |p|^2 on both axes; the gyro's heading is the truth's: small errors.
    np.testing.assert_allclose(windows.bases[:, 2, 0, 0], windows.bases[:, 2, 1, 1])
    assert np.all(windows.bases[:, 2, 0, 1] == 0.0)
    assert np.abs(windows.errors).max() < 0.2


def test_the_shares_of_timing_and_slip_are_those_of_replays_with_one_more_unit():
    # gyro_windows takes timing's and slip's shares from one replay (what the terms beside the
    # steps add at each window's end; the slip share propagated beside the covariance)
    # instead of replaying with one more of each: the same numbers.
    from tracked_kinematics.core.evaluate import cut
    from tracked_kinematics.core.evaluate.consistency import gyro_reset_windows
    from tracked_kinematics.core.covariance import TrackNoise
    rec = recording(1.0)
    pieces = cut(rec, 0, True, 0.7).pieces
    terms = NoiseModel(slip=0.01, timing=0.001).without_tracks()
    base = replace(terms, slip=0.02, timing=0.0, drift=0.0)
    args = (rec, pieces, ICR, GyroConfig(gyro_bias_sigma=0.001), TrackNoise(), terms)
    found = gyro_reset_windows(*args, base, 5.0, 0.1, 1.0,
                               unit=NoiseModel(track=0.0, floor=0.0, timing=1.0),
                               slip_share=True)
    gyro = found.gyro
    assert np.sum(gyro) >= 20
    # And slip's share, propagated beside the covariance, is the replay with one more slip.
    for share, more in ((found.unit, replace(base, timing=1.0)),
                        (found.slip, replace(base, slip=1.02))):
        other = gyro_reset_windows(*args, more, 5.0, 0.1, 1.0)
        np.testing.assert_array_equal(found.errors, other.errors)
        np.testing.assert_allclose(share[gyro], (other.covariances - found.covariances)[gyro],
                                   rtol=1e-9, atol=1e-15)
        assert np.trace(share[gyro].sum(0)) > 0.0    # not trivially equal: both zero


def test_a_replay_that_publishes_at_some_samples_is_the_full_one_there():
    # gyro_reset_windows wants the covariances at the windows' ends only: the others are
    # not computed, and the path, the sources and the wanted covariances are unchanged.
    t, left, right, w = drive()
    terms = NoiseModel(track=0.0, slip=0.01, timing=0.001, floor=0.0)
    unit = NoiseModel(track=0.0, floor=0.0, timing=1.0)
    resets = np.zeros(len(t), dtype=bool)
    resets[::40] = True
    kwargs = {'terms': terms, 'gyro_terms': replace(terms, drift=0.002), 'resets': resets,
              'unit': unit, 'slip_share': True}
    config = GyroConfig(gyro_bias_sigma=0.001)
    full = replay(t, left, right, t, w, ICR, config, **kwargs)
    some = replay(t, left, right, t, w, ICR, config, published_at=resets, **kwargs)
    np.testing.assert_array_equal(some[0], full[0])
    np.testing.assert_array_equal(some[1], full[1])
    assert 'gyro' in set(full[1][resets]) and 'encoders' in set(full[1][resets])
    for name in ('published', 'unit_published', 'slip_published'):
        got, expected = getattr(some[2], name), getattr(full[2], name)
        np.testing.assert_array_equal(got[resets], expected[resets])
        assert np.all(np.isnan(got[~resets])), name
        assert np.any(expected[resets] != 0.0), name    # not trivially equal
    # What the odometry holds at the end is the same (the last sample is not wanted).
    assert not resets[-1]
    assert some[2].pose == full[2].pose
    assert some[2].covariance_upper == full[2].covariance_upper
