"""Short-horizon prediction from track speeds and from commands."""

import math

import numpy as np
import pytest
from tracked_kinematics.core.drivetrain import DriveTrain, FirstOrderLag
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import ConstantIcr, IdealDiffDrive
from tracked_kinematics.core.prediction import (
    commands_from_twist, hold_speeds, predict_from_commands, predict_path)


def test_constant_speeds_give_the_closed_form_circle():
    model = IdealDiffDrive(0.5)
    v_left, v_right = hold_speeds(0.5, 1.0, horizon=2.0, dt=0.01)
    pred = predict_path(model, (), v_left, v_right, 0.01, pose0=(1.0, 2.0, 0.3))
    v, w = 0.75, 1.0
    yaw = 0.3 + w * 2.0
    radius = v / w
    expected = (1.0 + radius * (math.sin(yaw) - math.sin(0.3)),
                2.0 - radius * (math.cos(yaw) - math.cos(0.3)), yaw)
    np.testing.assert_allclose(pred.end, expected, atol=1e-9)
    assert len(pred.t) == 201 and pred.t[-1] == pytest.approx(2.0)
    np.testing.assert_array_equal(pred.poses[0], [1.0, 2.0, 0.3])


def test_slip_model_turns_less_than_ideal():
    icr = ConstantIcr(0.5, with_scales=False)
    v_left, v_right = hold_speeds(0.5, 1.0, 2.0, 0.01)
    slip = predict_path(icr, [0.4, -0.4, 0.0], v_left, v_right, 0.01)
    ideal = predict_path(IdealDiffDrive(0.5), (), v_left, v_right, 0.01)
    assert slip.end[2] == pytest.approx(ideal.end[2] * 0.5 / 0.8)


def test_ideal_drivetrain_prediction_equals_speed_prediction():
    model = ConstantIcr(0.5, with_scales=False)
    p = [0.35, -0.4, 0.05]
    cmd_left, cmd_right = np.linspace(0.0, 1.0, 100), np.linspace(0.5, 0.2, 100)
    from_cmd = predict_from_commands(model, p, DriveTrain(), cmd_left, cmd_right, 0.02)
    from_speeds = predict_path(model, p, cmd_left, cmd_right, 0.02)
    np.testing.assert_allclose(from_cmd.poses, from_speeds.poses, atol=1e-12)


def test_drivetrain_delay_and_lag_hold_the_vehicle_back():
    model = IdealDiffDrive(0.5)
    cmd_left, cmd_right = hold_speeds(1.0, 1.0, 2.0, 0.01)
    drive = DriveTrain(delay=0.2, max_accel=2.0, loop=FirstOrderLag(0.1))
    pred = predict_from_commands(model, (), drive, cmd_left, cmd_right, 0.01)
    assert np.all(pred.v_left[:20] == 0.0)
    np.testing.assert_allclose(pred.poses[:21, 0], 0.0)
    # Delay 0.2 s, ramp 0.5 s at 2 m/s^2, lag 0.1 s: about 0.2 + 0.25 + 0.1 m behind.
    assert 2.0 - 0.65 < pred.end[0] < 2.0 - 0.45
    running = predict_from_commands(model, (), drive, cmd_left, cmd_right, 0.01,
                                    speeds0=(1.0, 1.0))
    assert running.end[0] == pytest.approx(2.0, abs=1e-6)


def test_commands_from_twist_use_the_inverse_kinematics_with_scales():
    icr = IcrParams(0.5, 0.4, -0.4, 0.0, 1.0, 0.5)
    left, right = commands_from_twist(0.5, 0.5, icr, 1.0, 0.1)
    assert len(left) == 10
    np.testing.assert_allclose(left, 0.5 - 0.4 * 0.5)
    np.testing.assert_allclose(right, (0.5 + 0.4 * 0.5) / 0.5)


@pytest.mark.parametrize('args, match', [
    (([1.0], [1.0, 2.0], 0.1), 'differ'),
    (([math.nan], [1.0], 0.1), 'finite'),
    (([1.0], [1.0], 0.0), 'dt'),
])
def test_bad_inputs_are_clear_errors(args, match):
    with pytest.raises(ValueError, match=match):
        predict_path(IdealDiffDrive(0.5), (), *args)
