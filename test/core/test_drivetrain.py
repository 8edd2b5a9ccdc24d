"""Drive-train model of Fink & Stump sec. III-B: delay, acceleration limit, PID + DC motor."""

import math

import numpy as np
import pytest
from scipy import signal
from tracked_kinematics.core.drivetrain import DriveTrain, FirstOrderLag, PidMotor

DT = 0.001
PACKBOT = DriveTrain.fink_stump_packbot()


def test_table_ii_closed_loop_is_stable_with_unit_dc_gain():
    num, den = PACKBOT.transfer_function()
    # Eq. (8) with Table II: denominator J L s^3 + (J R + b L + K K_d) s^2 + ...
    np.testing.assert_allclose(den, [0.059 * 0.253, 0.059 * 0.254 + 0.456 * 0.253 + 0.0294 * 2.77,
                                     0.456 * 0.254 + 0.0294 ** 2 + 0.0294 * 56.49,
                                     0.0294 * 1.11])
    poles = np.roots(den)
    assert np.all(poles.real < 0.0)
    assert PACKBOT.dc_gain == pytest.approx(1.0)


def test_step_response_shows_delay_and_acceleration_limit():
    speeds = PACKBOT.simulate(np.full(3000, 2.0), DT)
    # Nothing moves before the command delay tau = 0.049 s.
    first = np.argmax(speeds > 1e-9) * DT
    assert first == pytest.approx(0.049, abs=1.5 * DT)
    # The shaped demand ramps at exactly a_max = 5.5 m/s^2; the loop follows it, with the
    # slight overshoot of its closed-loop poles (damping ratio 0.65).
    shaped = PACKBOT.shape(np.full(3000, 2.0), DT)
    assert np.max(np.diff(shaped)) / DT == pytest.approx(5.5)
    assert np.max(np.diff(speeds)) / DT <= 1.02 * 5.5
    # The ramp to 2 m/s takes 2 / 5.5 s: at 0.2 s the speed is well below the command.
    assert speeds[int(0.2 / DT)] < 0.9


def test_pid_with_integral_action_reaches_the_command():
    # Table II's tiny K_i leaves 6 % to close after the fast transient, slowly (pole at
    # -0.018 rad/s): steady state after a few minutes.
    slow = PACKBOT.simulate(np.full(30000, 1.0), 0.01)
    assert slow[int(2.0 / 0.01)] == pytest.approx(0.937, abs=0.01)
    assert slow[-1] == pytest.approx(1.0, abs=2e-3)
    # A stiffer integral gain closes the gap in seconds.
    snappy = DriveTrain(loop=PidMotor(kp=56.49, ki=60.0, kd=2.77, inertia=0.059, damping=0.456,
                                      resistance=0.254, inductance=0.253, motor_constant=0.0294))
    out = snappy.simulate(np.full(1000, 1.0), 0.01)
    assert out[-1] == pytest.approx(1.0, abs=1e-3)


def test_pid_without_integral_action_keeps_an_offset():
    drive = DriveTrain(loop=PidMotor(kp=56.49, ki=0.0, kd=2.77, inertia=0.059, damping=0.456,
                                     resistance=0.254, inductance=0.253, motor_constant=0.0294))
    out = drive.simulate(np.full(2000, 1.0), 0.01)
    assert out[-1] == pytest.approx(drive.dc_gain, abs=1e-6)
    assert drive.dc_gain < 0.95


def test_discretisation_is_exact_for_piecewise_linear_input():
    # First-order hold = the continuous system driven by the linear interpolation of the
    # samples, which scipy.signal.lsim integrates independently.
    t = np.arange(0.0, 5.0, 0.01)
    demand = np.clip(t - 0.5, 0.0, 1.0) + 0.3 * np.sin(2.0 * t)
    ours = PACKBOT.respond(demand, 0.01)
    _, reference, _ = signal.lsim(PACKBOT.transfer_function(), demand, t)
    np.testing.assert_allclose(ours, reference, atol=1e-9)


def test_first_order_lag_time_constant():
    drive = DriveTrain(delay=0.05, loop=FirstOrderLag(0.2))
    out = drive.simulate(np.ones(1000), DT)
    # 63.2 % of the step one time constant after the delay.
    assert out[int(round(0.25 / DT))] == pytest.approx(1.0 - math.exp(-1.0), abs=2e-3)


def test_steady_state_start_and_two_tracks():
    commands = np.tile([0.7, -0.4], (500, 1))
    out = PACKBOT.simulate(commands, 0.01, initial=[0.7, -0.4])
    np.testing.assert_allclose(out, commands, atol=1e-9)


def test_rate_limiter_and_speed_limit():
    drive = DriveTrain(max_accel=2.0, max_speed=1.0)
    commands = np.r_[np.zeros(5), np.full(100, 3.0), np.full(100, -3.0)]
    out = drive.simulate(commands, 0.01)
    assert np.max(np.abs(np.diff(out))) == pytest.approx(0.02)
    assert out.max() == pytest.approx(1.0) and out.min() == pytest.approx(-1.0)
    # Within the limits the ideal drive passes commands through.
    gentle = np.linspace(0.0, 0.5, 50)
    np.testing.assert_allclose(drive.simulate(gentle, 0.01), gentle)


def test_delay_is_exact_at_the_samples():
    commands = np.r_[np.zeros(10), np.ones(20)]
    for delay, lag in ((0.03, 3), (0.031, 4), (0.0, 0)):
        shaped = DriveTrain(delay=delay).shape(commands, 0.01)
        assert np.argmax(shaped > 0) == 10 + lag


def test_a_loop_of_another_kind_is_refused():
    # The ranges of delay, max_accel and the loop's values are checked where they enter
    # (test/params/test_params.py: drivetrain_from_values).
    with pytest.raises(ValueError, match='loop'):
        DriveTrain(loop='pid')


def test_unstable_loop_is_refused():
    with pytest.raises(ValueError, match='unstable'):
        # Routh: a2 a1 = 0.01 x 10001 < a3 a0 = 1e4, a high integral gain on a slow motor.
        PidMotor(kp=1e4, ki=1e4, kd=0.0, inertia=1.0, damping=0.0, resistance=0.01,
                 inductance=1.0, motor_constant=1.0)


def test_bad_time_step():
    with pytest.raises(ValueError, match='dt'):
        PACKBOT.simulate(np.ones(10), 0.0)
