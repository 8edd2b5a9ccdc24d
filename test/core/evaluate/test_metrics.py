"""The scores by hand: a straight path with a scale error, a circle with a known chi, evo's RPE."""

import math

from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from tracked_kinematics.core.evaluate import (
    cut, evo_path_pairs, horizon_members, odometry, relative_errors, rpe, summary,
    window_pairs)
from tracked_kinematics.core.identify import Recording
from tracked_kinematics.core.kinematics import IcrParams


def _recording(t, left, right, truth):
    return Recording(t, left, right, t, truth[:, 0], truth[:, 1], truth[:, 2])


def _ideal(track_width):
    icr = IcrParams.ideal(track_width)
    return icr.y_left, icr.y_right, icr.x, 1.0, 1.0


# --- a straight path, encoders 10 % long ----------------------------------------------------


@pytest.fixture(scope='module')
def straight():
    # 1 m/s for 20 s at 10 Hz; the encoders read 1.1 m per metre (a scale error of 10 %).
    t = np.arange(201) * 0.1
    truth = np.column_stack([t, np.zeros_like(t), np.zeros_like(t)])
    rec = _recording(t, 1.1 * t, 1.1 * t, truth)
    piece = cut(rec).pieces[0]
    return piece, odometry(piece, _ideal(0.5))


def test_straight_windows_have_the_scale_error_of_their_length(straight):
    piece, path = straight
    for length in (2.0, 5.0, 10.0):
        i, j = window_pairs(piece.t, length)
        assert len(i) == int(round((20.0 - length) / 0.1)) + 1
        position, heading = relative_errors(path, piece.truth, i, j)
        np.testing.assert_allclose(position, 0.1 * length, rtol=1e-9)
        np.testing.assert_allclose(heading, 0.0, atol=1e-12)


def test_straight_rpe_per_metre_by_hand(straight):
    piece, path = straight
    # Along the estimate (0.11 m per sample) from sample 0, the path reaches 1 m at sample 10
    # (1.1 m), then every 10 samples; each pair's estimate moved 1.1 m, the truth 1.0 m.
    ids = evo_path_pairs(path[:, :2], 1.0)
    np.testing.assert_array_equal(ids, np.arange(0, 201, 10))
    translation, rotation = rpe(path, piece.truth, 1.0)
    assert len(translation) == 20
    np.testing.assert_allclose(translation, 0.1, rtol=1e-9)
    stats = summary(translation)
    assert stats['rmse'] == pytest.approx(0.1) and stats['mean'] == pytest.approx(0.1)
    # Per 10 m: samples 0, 91 (10.01 m) and 182 (20.02 m), 9.1 m of truth each.
    translation, _ = rpe(path, piece.truth, 10.0)
    np.testing.assert_allclose(translation, [0.91, 0.91], rtol=1e-9)


# --- a circle with a known steering efficiency ---------------------------------------------


def test_circle_with_known_chi_against_ideal_drive_by_hand():
    # Tracks at 0.5 and 1.0 m/s, track width 0.5 m, chi = 0.5 (ICRs at +-0.5 m): the truth
    # turns at 0.5 rad/s on a 1.5 m radius; ideal drive believes 1 rad/s on 0.75 m.
    track, chi, v_left, v_right = 0.5, 0.5, 0.5, 1.0
    t = np.arange(0, 20.0001, 0.05)
    w = (v_right - v_left) / (track / chi)
    v = 0.5 * (v_left + v_right)
    radius = v / w
    truth = np.column_stack([radius * np.sin(w * t), radius * (1 - np.cos(w * t)), w * t])
    rec = _recording(t, v_left * t, v_right * t, truth)
    piece = cut(rec).pieces[0]
    ideal = odometry(piece, _ideal(track))
    true_icr = IcrParams.symmetric(track, chi)
    exact = odometry(piece, (true_icr.y_left, true_icr.y_right, true_icr.x, 1.0, 1.0))
    np.testing.assert_allclose(exact, piece.truth, atol=1e-9)
    i, j = window_pairs(piece.t, 2.0)
    position, heading = relative_errors(ideal, piece.truth, i, j)
    # After 2 s: truth at (1.5 sin 1, 1.5 (1 - cos 1)), ideal at (0.75 sin 2, 0.75 (1 - cos 2))
    # in the frame of the start, headings 1 and 2 rad.
    expected = math.hypot(1.5 * math.sin(1.0) - 0.75 * math.sin(2.0),
                          1.5 * (1 - math.cos(1.0)) - 0.75 * (1 - math.cos(2.0)))
    np.testing.assert_allclose(position, expected, rtol=1e-9)
    np.testing.assert_allclose(heading, 1.0, rtol=1e-9)


# --- evo's RPE -------------------------------------------------------------------------------


def _se3(pose):
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _evo_rpe(reference, estimate, delta):
    """Compute evo's RPE (translation, delta in m, consecutive pairs) as evo 1.38 does."""
    poses = [_se3(p) for p in estimate]
    ids, previous, current = [0], poses[0], 0.0
    for i, pose in enumerate(poses[1:], start=1):
        current += np.linalg.norm(pose[:3, 3] - previous[:3, 3])
        previous = pose
        if current >= delta:
            ids.append(i)
            current = 0.0
    errors, angles = [], []
    for i, j in zip(ids, ids[1:]):
        q_rel = np.linalg.inv(_se3(reference[i])) @ _se3(reference[j])
        p_rel = np.linalg.inv(poses[i]) @ poses[j]
        e = np.linalg.inv(q_rel) @ p_rel
        errors.append(np.linalg.norm(e[:3, 3]))
        angles.append(abs(math.atan2(e[1, 0], e[0, 0])))
    return ids, np.array(errors), np.array(angles)


def test_rpe_of_a_small_trajectory_by_hand():
    # Five poses; the estimate walks 0.6 m steps, so evo chooses samples 0, 2 and 4 (1.2 m
    # apart); the hand-computed pair is the second.
    reference = np.array([[0, 0, 0], [0.5, 0, 0], [1.0, 0, 0.1], [1.5, 0.1, 0.2],
                          [2.0, 0.2, 0.3]])
    estimate = np.array([[0, 0, 0], [0.6, 0, 0], [1.2, 0, 0], [1.8, 0, 0], [2.4, 0, 0]])
    np.testing.assert_array_equal(evo_path_pairs(estimate[:, :2], 1.0), [0, 2, 4])
    translation, rotation = rpe(estimate, reference, 1.0)
    # Reference from sample 0 to 2: (1.0, 0), turned 0.1; from 2 to 4, in the frame of
    # sample 2 (yaw 0.1): (1.0, 0.2) rotated by -0.1 rad, turned 0.2.
    c, s = math.cos(0.1), math.sin(0.1)
    q = (c * 1.0 + s * 0.2, -s * 1.0 + c * 0.2)
    np.testing.assert_allclose(translation, [0.2, math.hypot(1.2 - q[0], 0.0 - q[1])])
    np.testing.assert_allclose(rotation, [0.1, 0.2])
    _, errors, angles = _evo_rpe(reference, estimate, 1.0)
    np.testing.assert_allclose(translation, errors)
    np.testing.assert_allclose(rotation, angles)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), delta=st.sampled_from([0.3, 1.0, 2.5]))
def test_rpe_equals_evo_on_random_trajectories(seed, delta):
    rng = np.random.default_rng(seed)
    n = 60
    steps = rng.uniform(0.0, 0.4, n)
    turns = rng.normal(0.0, 0.3, n)
    yaw = np.cumsum(turns)
    reference = np.column_stack([np.cumsum(steps * np.cos(yaw)), np.cumsum(steps * np.sin(yaw)),
                                 yaw])
    estimate = reference + rng.normal(0.0, 0.05, (n, 3)) + np.linspace(0, 1, n)[:, None]
    ids, errors, angles = _evo_rpe(reference, estimate, delta)
    np.testing.assert_array_equal(evo_path_pairs(estimate[:, :2], delta), ids)
    translation, rotation = rpe(estimate, reference, delta)
    np.testing.assert_allclose(translation, errors, atol=1e-12)
    np.testing.assert_allclose(rotation, angles, atol=1e-12)


# --- windows, horizons, statistics ------------------------------------------------------------


def test_windows_end_at_the_last_sample_within_their_length():
    t = np.array([0.0, 0.4, 1.0, 1.7, 2.0, 2.9, 3.0])
    i, j = window_pairs(t, 1.0)
    # From 0: the last sample <= 1.0 is 1.0; from 0.4: 1.0; from 1.0: 2.0; from 1.7: 2.0
    # (2.9 is beyond 2.7); from 2.0: 3.0; 2.9 and 3.0 have no full window.
    np.testing.assert_array_equal(i, [0, 1, 2, 3, 4])
    np.testing.assert_array_equal(j, [2, 2, 4, 4, 6])


def test_horizon_members_and_scores():
    t = np.arange(6) * 0.5
    starts, owner, member = horizon_members(t, 1.0)
    np.testing.assert_array_equal(starts, [0, 1, 2, 3])
    np.testing.assert_array_equal(owner, [0, 0, 1, 1, 2, 2, 3, 3])
    np.testing.assert_array_equal(member, [1, 2, 2, 3, 3, 4, 4, 5])


def test_summary_has_evos_statistics():
    stats = summary([3.0, 4.0])
    assert stats == {'n': 2, 'rmse': pytest.approx(math.sqrt(12.5)), 'mean': 3.5,
                     'median': 3.5, 'std': 0.5, 'min': 3.0, 'max': 4.0, 'sse': 25.0,
                     'p90': pytest.approx(3.9)}
    empty = summary([])
    assert empty['n'] == 0 and empty['rmse'] is None


def test_rpe_pairs_from_the_reference_are_the_same_for_every_estimate():
    rng = np.random.default_rng(7)
    yaw = np.cumsum(rng.normal(0.0, 0.2, 80))
    steps = rng.uniform(0.05, 0.3, 80)
    reference = np.column_stack([np.cumsum(steps * np.cos(yaw)), np.cumsum(steps * np.sin(yaw)),
                                 yaw])
    ids = evo_path_pairs(reference[:, :2], 1.0)
    for scale in (0.9, 1.2):
        estimate = reference * [scale, scale, 1.0]
        translation, _ = rpe(estimate, reference, 1.0, pairs_from_reference=True)
        expected, _ = relative_errors(estimate, reference, ids[:-1], ids[1:])
        np.testing.assert_allclose(translation, expected)
