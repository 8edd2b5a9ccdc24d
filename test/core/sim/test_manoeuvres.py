"""Manoeuvre sets: shapes, limits, reproducibility, the Fink & Stump sweep grid."""

import numpy as np
import pytest
from tracked_kinematics.core.sim.manoeuvres import (fink_stump_sweep, manoeuvre, MANOEUVRES,
                                                    random_drive, spin_in_place, trapezoid)

DT = 0.02


@pytest.mark.parametrize('name', MANOEUVRES)
def test_every_set_fills_the_duration_within_limits_and_ends_at_rest(name):
    commands = manoeuvre(name, 120.0, DT, 0.42, 1.0, np.random.default_rng(3))
    assert commands.shape == (6000, 2)
    assert np.all(np.isfinite(commands))
    assert np.max(np.abs(commands)) <= 1.0 + 1e-12
    assert np.allclose(commands[0], 0.0, atol=0.05) and np.all(commands[-1] == 0.0)
    again = manoeuvre(name, 120.0, DT, 0.42, 1.0, np.random.default_rng(3))
    np.testing.assert_array_equal(commands, again)


@pytest.mark.parametrize('name', ['random', 'mixed'])
def test_random_sets_depend_on_the_seed(name):
    one = manoeuvre(name, 60.0, DT, 0.42, 1.0, np.random.default_rng(1))
    two = manoeuvre(name, 60.0, DT, 0.42, 1.0, np.random.default_rng(2))
    assert not np.array_equal(one, two)


def test_random_drive_looks_like_manual_driving():
    commands = random_drive(900.0, DT, 1.0, np.random.default_rng(0))
    v_left, v_right = commands.T
    turning = (v_right - v_left) / 0.42
    forward = 0.5 * (v_left + v_right)
    # Both turn directions, counter-rotation (spins, pivots), reversing, and stops.
    assert np.mean(turning > 0.2) > 0.1 and np.mean(turning < -0.2) > 0.1
    assert np.mean(v_left * v_right < -0.01) > 0.03
    assert np.mean(forward < -0.1) > 0.03
    assert np.mean(np.hypot(v_left, v_right) < 0.02) > 0.03
    # Smooth: the stick filter bounds the step-to-step change.
    assert np.max(np.abs(np.diff(commands, axis=0))) < 2.0 * DT / 0.4


def test_trapezoid_profile():
    profile = trapezoid(2.0, 1.0, 5.0, 0.01)
    assert profile.max() == pytest.approx(1.0)
    assert np.max(np.abs(np.diff(profile))) <= 5.0 * 0.01 + 1e-12
    triangle = trapezoid(0.2, -2.0, 1.0, 0.01)
    assert triangle.min() == pytest.approx(-0.1, abs=0.01)


def test_fink_stump_sweep_reproduces_the_papers_grid():
    # Packbot (B ~ 0.4 m, 2 m/s): v_trav = 0.5 .. 2.0 m/s x kappa_trav = +-1/4 .. +-2 1/m,
    # every pair whose faster tread stays within 2 m/s; paths of about 4 m.
    dt, width = 0.01, 0.40
    commands = fink_stump_sweep(dt, width, 2.0)
    moving = np.any(commands != 0.0, axis=1)
    starts = np.flatnonzero(np.diff(moving.astype(int)) == 1) + 1
    stops = np.flatnonzero(np.diff(moving.astype(int)) == -1) + 1
    speeds = np.round(np.arange(0.5, 2.01, 0.1), 10)
    kappas = [0.25, 0.5, 0.75, 1.0, 1.5, 2.0]
    expected = [(v, k) for v in speeds for k in kappas for _ in (1, -1)
                if v * (1.0 + 0.5 * k * width) <= 2.0 + 1e-9]
    assert len(starts) == len(stops) == len(expected)
    for (v, _), a, b in zip(expected, starts, stops):
        piece = commands[a:b]
        forward = piece.mean(axis=1)
        assert forward.max() == pytest.approx(v, abs=0.03)
        assert np.sum(forward) * dt == pytest.approx(4.0, abs=0.05)
    assert np.max(np.abs(commands)) <= 2.0 + 1e-9


def test_sweep_signs_follow_the_curvature():
    commands = fink_stump_sweep(0.01, 0.4, 2.0, speeds=[1.0], curvatures=[1.0, -1.0])
    moving = np.any(commands != 0.0, axis=1)
    edges = np.flatnonzero(np.diff(moving.astype(int)))
    left_turn = commands[edges[0] + 1:edges[1] + 1]
    right_turn = commands[edges[2] + 1:edges[3] + 1]
    assert np.all(left_turn[:, 1] >= left_turn[:, 0])     # kappa > 0: left, V_r > V_l
    assert np.all(right_turn[:, 1] <= right_turn[:, 0])


def test_sweep_without_feasible_pair():
    with pytest.raises(ValueError, match='no \\(speed, curvature\\) pair'):
        fink_stump_sweep(0.01, 0.4, 1.0, speeds=[2.0])


def test_spin_in_place_counter_rotates_both_ways():
    commands = spin_in_place(0.01, 1.0)
    np.testing.assert_array_equal(commands[:, 0], -commands[:, 1])
    assert commands[:, 1].max() == 1.0 and commands[:, 1].min() == -1.0


def test_unknown_manoeuvre_and_bad_duration():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match='unknown manoeuvre set'):
        manoeuvre('slalom', 10.0, DT, 0.42, 1.0, rng)
    with pytest.raises(ValueError, match='duration'):
        manoeuvre('random', -1.0, DT, 0.42, 1.0, rng)
