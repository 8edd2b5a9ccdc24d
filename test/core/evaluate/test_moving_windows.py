"""The windows in which the vehicle moves: mean track speed, and figures that ignore a stop."""

from helpers.vehicle_sim import from_track_speeds
import numpy as np
import pytest
from tracked_kinematics.core.evaluate import (
    Candidate, cut, Data, evaluate, mean_track_speeds, moving_windows, Settings, window_pairs)
from tracked_kinematics.core.identify import Recording
from tracked_kinematics.core.kinematics import IcrParams

ICR = IcrParams(0.5, 0.4, -0.45, 0.03, 1.02, 0.98)
RATE, GT_RATE = 50.0, 10.0


def _drive_then_stop(idle, seconds=30.0):
    """30 s of driving (truth from a slipping model), then ``idle`` s standing still."""
    n = int(seconds * RATE)
    t = np.arange(n + int(idle * RATE) + 1) / RATE
    left = np.where(t < seconds, 0.6 + 0.3 * np.sin(t / 1.7), 0.0)
    right = np.where(t < seconds, 0.6 + 0.3 * np.sin(t / 2.3 + 1.0), 0.0)
    return from_track_speeds(left, right, ICR, RATE, GT_RATE)


def _windows(recording, min_speed):
    candidates = [Candidate('ideal', IcrParams.ideal(ICR.track_width))]
    settings = Settings(windows=(5.0, 10.0), min_speed=min_speed, track_width=ICR.track_width)
    return evaluate([Data(recording)], candidates, settings).models['ideal']['odometry']


def test_mean_track_speed_is_the_mean_of_both_tracks_absolute_speeds():
    t = np.arange(501) / RATE
    # A turn on the spot at 0.5 m/s per track moves; then 5 s still.
    left = np.where(t <= 5.0, -0.5 * t, -2.5)
    right = -left
    gt_t = t[::5]
    zero = np.zeros(len(gt_t))
    piece = cut(Recording(t, left, right, gt_t, zero, zero, zero)).pieces[0]
    i, j = window_pairs(piece.t, 2.0)
    speeds = mean_track_speeds(piece, i, j)
    start = piece.t[i]
    np.testing.assert_allclose(speeds[start <= 3.0], 0.5, atol=1e-12)
    np.testing.assert_allclose(speeds[start >= 5.0], 0.0, atol=1e-12)
    # Half the window moving: half the speed.
    np.testing.assert_allclose(speeds[np.isclose(start, 4.0)], 0.25, atol=1e-12)
    kept, _, total = moving_windows(piece, 2.0, 0.24)
    assert total == len(i)
    assert piece.t[kept].max() == pytest.approx(4.0)
    everything, _, _ = moving_windows(piece, 2.0, None)
    np.testing.assert_array_equal(everything, i)


def test_a_long_stop_changes_the_all_window_figures_only():
    # The same drive with a stop one window long and with a 5-min stop: the windows in which
    # the tracks move (those that reach into the stop too) are the same.
    short, long = _drive_then_stop(10.0), _drive_then_stop(300.0)
    for key in ('5', '10'):
        a = _windows(short, 0.1)['windows'][key]
        b = _windows(long, 0.1)['windows'][key]
        assert a['n'] == b['n'] > 0
        assert b['n_total'] > a['n_total'] > a['n']
        for figure in ('mean_position_error_m', 'p90_position_error_m',
                       'mean_heading_error_rad', 'drift_pct'):
            assert b[figure] == pytest.approx(a[figure], rel=1e-9)
            assert a[figure] > 0
        all_a = _windows(short, None)['windows'][key]
        all_b = _windows(long, None)['windows'][key]
        assert (all_a['n'], all_b['n']) == (a['n_total'], b['n_total'])
        # Idle windows have no error: they dilute the mean.
        assert all_b['mean_position_error_m'] < 0.5 * all_a['mean_position_error_m']
        assert all_a['mean_position_error_m'] < a['mean_position_error_m']
