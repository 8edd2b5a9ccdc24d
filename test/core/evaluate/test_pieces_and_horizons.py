"""Pieces (gaps, jumps), odometry along them, and the predictions over horizons."""

import math

from helpers.vehicle_sim import from_track_speeds
import numpy as np
import pytest
from tracked_kinematics.core.drivetrain import DriveTrain, FirstOrderLag
from tracked_kinematics.core.evaluate import (
    command_horizons, Commands, cut, encoder_horizons, horizon_members, odometry,
    relative_errors)
from tracked_kinematics.core.evaluate.horizons import start_speeds
from tracked_kinematics.core.identify import dead_reckoning, Recording
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import ConstantIcr
from tracked_kinematics.core.prediction import predict_from_commands

ICR = IcrParams(0.5, 0.4, -0.45, 0.03, 1.02, 0.98)
PARAMS = (ICR.y_left, ICR.y_right, ICR.x, ICR.scale_left, ICR.scale_right)


def _drive(seconds=30.0, rate=50.0, gt_rate=10.0, seed=0):
    """Tracks following smooth commands; truth from the true model; 50 Hz encoders."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * rate) + 1) / rate
    left = 0.6 + 0.3 * np.sin(t / 1.7 + rng.uniform(0, 6))
    right = 0.6 + 0.3 * np.sin(t / 2.3 + rng.uniform(0, 6))
    rec = from_track_speeds(left, right, ICR, rate, gt_rate)
    return rec, Commands(t, np.column_stack([left, right]))


def test_odometry_of_a_piece_is_identifys_dead_reckoning():
    rec, _ = _drive()
    piece = cut(rec).pieces[0]
    model = ConstantIcr(ICR.track_width)
    _, x, y, yaw = dead_reckoning(model, model.from_icr(ICR), rec)
    np.testing.assert_allclose(odometry(piece, PARAMS), np.column_stack([x, y, yaw]),
                               atol=1e-12)
    np.testing.assert_allclose(odometry(piece, PARAMS), piece.truth, atol=1e-9)


def test_gaps_and_jumps_cut_pieces():
    rec, _ = _drive()
    # A 2-s encoder gap at 10 s (9.98-12.02 s: the 22 ground-truth intervals from 9.9 to
    # 12.1 s overlap it), and a 3-m ground-truth jump at 20 s (re-localised).
    enc = (rec.enc_t < 10.0) | (rec.enc_t > 12.0)
    gt_x = np.where(rec.gt_t >= 20.0, rec.gt_x + 3.0, rec.gt_x)
    broken = Recording(rec.enc_t[enc], rec.left[enc], rec.right[enc], rec.gt_t, gt_x,
                       rec.gt_y, rec.gt_yaw)
    result = cut(broken)
    assert (result.gaps, result.jumps) == (22, 1)
    assert [(round(p.t[0], 1), round(p.t[-1], 1)) for p in result.pieces] == [
        (0.0, 9.9), (12.1, 19.9), (20.0, 30.0)]
    assert len(cut(broken, jumps=False).pieces) == 2
    for piece in result.pieces:
        np.testing.assert_allclose(odometry(piece, PARAMS), piece.truth, atol=1e-9)


def test_encoder_horizons_equal_odometry_restarted_at_each_start():
    rec, _ = _drive(seed=1)
    piece = cut(rec).pieces[0]
    ideal = IcrParams.ideal(ICR.track_width)
    params = (ideal.y_left, ideal.y_right, ideal.x, 1.0, 1.0)
    errors = encoder_horizons(piece, 2.0, lambda times: params)
    starts, owner, member = horizon_members(piece.t, 2.0)
    path = odometry(piece, params)
    translation, rotation = relative_errors(path, piece.truth, starts[owner], member)
    count = np.bincount(owner)
    np.testing.assert_allclose(errors.rms_translation,
                               np.sqrt(np.bincount(owner, translation ** 2) / count))
    np.testing.assert_allclose(errors.rms_rotation,
                               np.sqrt(np.bincount(owner, rotation ** 2) / count))
    np.testing.assert_allclose(errors.final_translation, translation[np.cumsum(count) - 1])
    assert len(errors) == len(starts) == 281
    # Per-horizon parameters: the true model for even horizons only.
    mixed = encoder_horizons(piece, 2.0, lambda times: tuple(
        np.where(np.arange(len(times)) % 2 == 0, a, b) for a, b in zip(PARAMS, params)))
    np.testing.assert_allclose(mixed.rms_translation[::2], 0.0, atol=1e-9)
    np.testing.assert_allclose(mixed.rms_translation[1::2], errors.rms_translation[1::2])


def test_command_prediction_is_the_cores_through_the_drive_train():
    rec, commands = _drive(seed=2)
    piece = cut(rec).pieces[0]
    drive = DriveTrain(delay=0.1, max_accel=1.0, loop=FirstOrderLag(0.2))
    errors = command_horizons(piece, 2.0, commands, lambda times: PARAMS, drive, dt=0.05)
    assert len(errors) == 280   # the first needs the command of 0.1 s before the start
    # One horizon by hand with the core's predictor: the commands of t0 - 0.1 ... t0 + 1.9
    # s through the drive train (zero delay) from the measured speeds, then the model.
    k = 100
    t0 = piece.t[k]
    held, _ = commands.held(t0 + (np.arange(40) - 2) * 0.05, 0.5)
    speeds0 = start_speeds(piece, np.array([k]))[0]
    model = ConstantIcr(ICR.track_width)
    pred = predict_from_commands(model, model.from_icr(ICR), DriveTrain(0.0, 1.0, math.inf,
                                                                        FirstOrderLag(0.2)),
                                 held[:, 0], held[:, 1], 0.05, speeds0=speeds0)
    members = np.flatnonzero((piece.t > t0) & (piece.t <= t0 + 2.0 + 1e-9))
    c, s = math.cos(piece.truth[k, 2]), math.sin(piece.truth[k, 2])
    d = piece.truth[members, :2] - piece.truth[k, :2]
    truth = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
    at = np.searchsorted(pred.t, piece.t[members] - t0 - 1e-9)
    position = np.hypot(*(pred.poses[at, :2] - truth).T)
    mine = np.flatnonzero(np.isclose(errors.t0, t0))[0]
    assert errors.rms_translation[mine] == pytest.approx(np.sqrt(np.mean(position ** 2)),
                                                         rel=1e-9)


def test_naive_prediction_with_true_speeds_and_model_is_exact():
    rec, commands = _drive(seed=3)
    piece = cut(rec).pieces[0]
    errors = command_horizons(piece, 2.0, commands, lambda times: PARAMS, None, dt=0.02)
    # The commands are the track speeds (held over each 20 ms step): exact integration.
    assert np.max(errors.rms_translation) < 1e-9
    assert np.max(errors.final_rotation) < 1e-9


def test_horizons_without_fresh_commands_are_skipped():
    rec, commands = _drive(seed=4)
    piece = cut(rec).pieces[0]
    # Commands only during 5-15 s (a joystick drove the rest, unlogged).
    keep = (commands.t >= 5.0) & (commands.t <= 15.0)
    some = Commands(commands.t[keep], commands.values[keep])
    errors = command_horizons(piece, 2.0, some, lambda times: PARAMS, None, max_age=0.5)
    # The last command (15 s) is in force until 15.5 s; a horizon needs them to t0 + 1.95 s.
    assert errors.t0.min() == pytest.approx(5.0) and errors.t0.max() == pytest.approx(13.5)
    assert len(errors) == 86
