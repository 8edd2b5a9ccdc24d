"""Trajectory simulation: twist table, drive train, dynamics, exact integration, sensors."""

from dataclasses import replace

import numpy as np
import pytest
from tracked_kinematics.core.drivetrain import DriveTrain, FirstOrderLag
from tracked_kinematics.core.integration import relative_pose
from tracked_kinematics.core.models import ConstantIcr
from tracked_kinematics.core.sim.dynamics import StationarySolver, Vehicle
from tracked_kinematics.core.sim.manoeuvres import manoeuvre
from tracked_kinematics.core.sim.simulation import (Encoders, GroundTruth, Robot, simulate,
                                                    TwistTable)

AURIGA = Vehicle(0.42, 0.7, 0.15, 258.0, com_x=0.04, com_y=0.015, mu_x=0.6, mu_y=0.75,
                 max_track_speed=1.0)
LOADED = replace(AURIGA, com_height=0.3)
DT = 0.01


@pytest.fixture(scope='module')
def tables():
    return {AURIGA: TwistTable(AURIGA), LOADED: TwistTable(LOADED)}


def test_a_vehicles_default_table_is_built_once_and_shared(tables, monkeypatch):
    table = TwistTable.of(replace(AURIGA))        # an equal vehicle, another object
    assert TwistTable.of(AURIGA) is table
    assert TwistTable.of(LOADED) is not table
    v_left, v_right = np.linspace(-1.0, 1.0, 9), np.linspace(1.0, -0.5, 9)
    np.testing.assert_array_equal(np.stack(table(v_left, v_right)),
                                  np.stack(tables[AURIGA](v_left, v_right)))

    def built(*args, **kwargs):
        raise AssertionError('a second table of the vehicle was built')

    # A simulation given no table takes the shared one.
    monkeypatch.setattr(TwistTable, '__init__', built)
    run = simulate(Robot(AURIGA), np.full((3, 2), 0.5), DT)
    assert run.pose[-1, 0] > 0.0


@pytest.fixture(scope='module')
def commands():
    return manoeuvre('mixed', 60.0, DT, 0.42, 1.0, np.random.default_rng(7))


@pytest.mark.parametrize('vehicle', [AURIGA, LOADED])
def test_twist_table_matches_the_solver(tables, vehicle):
    rng = np.random.default_rng(1)
    v_left, v_right = rng.uniform(-1.0, 1.0, (2, 200))
    expected, ok = StationarySolver(vehicle).solve_many(v_left, v_right)
    assert np.all(ok)
    got = np.stack(tables[vehicle](v_left, v_right), axis=-1)
    np.testing.assert_allclose(got, expected, atol=5e-4)


def test_twist_table_shapes_and_standstill(tables):
    table = tables[AURIGA]
    v_x, v_y, w = table(0.0, 0.0)
    assert v_x.shape == () and v_x == 0.0 and w == 0.0
    v_x, v_y, w = table(np.full((2, 3), 0.5), np.full((2, 3), 0.5))
    assert v_x.shape == (2, 3)
    np.testing.assert_allclose(v_x, 0.5, atol=1e-6)
    np.testing.assert_allclose(w, 0.0, atol=1e-6)


def test_quasi_static_run_follows_the_constant_icr_model(tables, commands):
    # Without inertia the tread ICRs are constant, so integrating the exact encoder travel
    # through the averaged ICRs must reproduce the true path.
    robot = Robot(AURIGA, DriveTrain(delay=0.03, max_accel=1.5, loop=FirstOrderLag(0.15)))
    run = simulate(robot, commands, DT, tables[AURIGA])
    icr = robot.true_icr(n=11)
    model = ConstantIcr(icr.track_width, with_scales=False)
    travel = np.diff(run.joint_position, axis=0) * robot.encoders.sprocket_radius
    x, y, theta = model.integrate(model.from_icr(icr), travel[:, 0], travel[:, 1], DT)
    assert run.distance > 20.0
    assert np.hypot(x[-1] - run.pose[-1, 0], y[-1] - run.pose[-1, 1]) < 0.01 * run.distance
    best = run.best_constant_icr(0.42)
    assert best.y_left == pytest.approx(icr.y_left, abs=2e-3)
    assert best.y_right == pytest.approx(icr.y_right, abs=2e-3)


def test_load_transfer_makes_the_constant_model_approximate(tables, commands):
    robot = Robot(LOADED)
    run = simulate(robot, commands, DT, tables[LOADED])
    icr = robot.true_icr(n=11)
    model = ConstantIcr(0.42, with_scales=False)
    travel = np.diff(run.joint_position, axis=0) * robot.encoders.sprocket_radius
    x, y, theta = model.integrate(model.from_icr(icr), travel[:, 0], travel[:, 1], DT)
    ideal = ConstantIcr(0.42, with_scales=False)
    xi, yi, thi = ideal.integrate(ideal.initial(), travel[:, 0], travel[:, 1], DT)
    err_icr = abs(theta[-1] - run.pose[-1, 2])
    err_ideal = abs(thi[-1] - run.pose[-1, 2])
    assert err_icr < 0.1 * err_ideal


def test_drive_train_and_scales_in_the_chain(tables):
    commands = np.tile([0.5, 0.5], (300, 1))
    robot = Robot(AURIGA, DriveTrain(delay=0.05, max_accel=1.0),
                  Encoders(sprocket_radius=0.1, scale_left=1.02, scale_right=0.98))
    run = simulate(robot, commands, DT, tables[AURIGA])
    assert np.all(run.nominal[:5] == 0.0) and run.nominal[5, 0] > 0.0
    np.testing.assert_allclose(run.true_speeds, run.nominal * [1.02, 0.98])
    # Reported velocities are nominal: rad/s of the sprocket.
    np.testing.assert_allclose(run.joint_velocity, run.nominal / 0.1)
    # Unequal true speeds turn the vehicle right although the commands are straight.
    assert run.pose[-1, 2] < -0.01


def test_encoder_quantisation_and_reproducibility(tables, commands):
    robot = Robot(AURIGA, encoders=Encoders(sprocket_radius=0.1, ticks_per_revolution=2000))
    run = simulate(robot, commands, DT, tables[AURIGA], rng=np.random.default_rng(5))
    tick = 2 * np.pi / 2000
    steps = np.diff(run.joint_position, axis=0) / tick
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    exact = simulate(Robot(AURIGA), commands, DT, tables[AURIGA])
    assert np.max(np.abs(run.joint_position - exact.joint_position)) <= tick
    again = simulate(robot, commands, DT, tables[AURIGA], rng=np.random.default_rng(5))
    np.testing.assert_array_equal(run.joint_position, again.joint_position)


def test_ground_truth_rate_exactness_and_noise(tables, commands):
    robot = Robot(AURIGA)
    clean = simulate(robot, commands, DT, tables[AURIGA], GroundTruth(rate=7.0))
    # 7 Hz does not divide 100 Hz: poses between encoder samples come from the exact arcs.
    assert np.allclose(np.diff(clean.gt_t), 1.0 / 7.0)
    k = np.searchsorted(clean.t, clean.gt_t) - 1
    tau = clean.gt_t - clean.t[k]
    inside = (tau > 1e-6) & (k < len(clean.twist))
    dx, dy, dth = relative_pose(*clean.pose[k[inside]].T, *clean.gt_pose_true[inside].T)
    expected_th = clean.twist[k[inside], 2] * tau[inside]
    np.testing.assert_allclose(dth, expected_th, atol=1e-12)
    on_grid = simulate(robot, commands, DT, tables[AURIGA], GroundTruth(rate=10.0))
    np.testing.assert_allclose(on_grid.gt_pose_true, on_grid.pose[::10], atol=1e-12)
    noisy = simulate(robot, commands, DT, tables[AURIGA],
                     GroundTruth(rate=10.0, position_noise=0.01, yaw_noise=0.02),
                     rng=np.random.default_rng(2))
    err = noisy.gt_pose - noisy.gt_pose_true
    err[:, 2] = (err[:, 2] + np.pi) % (2 * np.pi) - np.pi
    assert np.std(err[:, :2]) == pytest.approx(0.01, rel=0.15)
    assert np.std(err[:, 2]) == pytest.approx(0.02, rel=0.15)


def test_bad_inputs(tables):
    robot = Robot(AURIGA)
    with pytest.raises(ValueError, match='shape'):
        simulate(robot, np.zeros((10, 3)), DT, tables[AURIGA])
    with pytest.raises(ValueError, match='finite'):
        simulate(robot, np.full((10, 2), np.nan), DT, tables[AURIGA])
    with pytest.raises(ValueError, match='another vehicle'):
        simulate(robot, np.zeros((10, 2)), DT, tables[LOADED])
