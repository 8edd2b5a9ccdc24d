"""plan_trajectory: bounded work, outputs all or none, one-line errors (issue 14 items 9-13).

The planner itself and the command line's main path: test/core/plan/test_planning.py.
"""

import errno
import math
from pathlib import Path
import re
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from tracked_kinematics.core.command import CommandLimits
from tracked_kinematics.core.drivetrain import DriveTrain
from tracked_kinematics.core.models import IdealDiffDrive
from tracked_kinematics.core.plan import Planner
from tracked_kinematics.offline.cli import plan_trajectory
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.planning import limits_from
from tracked_kinematics.params import limits_from_values

BIN = Path(sys.executable).parent
TERRAIN = Path(__file__).resolve().parents[2] / 'config' / 'auriga_alpha_hard_floor.yaml'
GOAL = ['--params', str(TERRAIN), '--goal', '1.0', '0.3', '0.2', '--horizon', '4']


def call(argv, capsys):
    try:
        status = plan_trajectory.main([str(a) for a in argv])
    except SystemExit as exc:
        status = exc.code
    out, err = capsys.readouterr()
    return status, out, err


@pytest.mark.parametrize('argv, message', [
    (['--horizon', '1e6'], '--horizon: must be in [0.8, 30] s, got 1e6'),
    (['--horizon', '0.1'], '--horizon: must be in [0.8, 30] s, got 0.1'),
    (['--dt', '1e-9'], '--dt: must be in [0.005, 0.1] s, got 1e-9'),
    (['--tolerance', '0', '0'], '--tolerance: must be in [0.001, 10], got 0'),
    (['--max-track-speed', '1e300'], '--max-track-speed: must be in [0.01, 10] m/s'),
    (['--max-track-accel', '-1'], '--max-track-accel: must be in [0.01, 100] m/s^2'),
    (['--speed', 'inf'], '--speed: must be a finite number in [0.01, 10] m/s'),
    (['--time-limit', '0'], '--time-limit: must be in [1, 3600] s'),
])
def test_absurd_numbers_are_one_line_exit_2(tmp_path, capsys, argv, message):
    status, _, err = call(GOAL + argv + ['--csv', tmp_path / 'p.csv'], capsys)
    assert status == 2 and err.count('\n') == 1 and message in err, err
    assert err.startswith('plan_trajectory: error: argument ')
    assert list(tmp_path.iterdir()) == []


def test_a_far_goal_is_refused_up_front(tmp_path):
    # No answer after 150 s before (issue 14 item 12): the default horizon is capped, and a
    # goal the limits cannot reach within it is refused before optimising.
    done = subprocess.run([str(BIN / 'plan_trajectory'), '--params', str(TERRAIN), '--goal',
                           '100', '0', '0', '--csv', 'p.csv'], cwd=tmp_path,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 1
    assert done.stderr.startswith('plan_trajectory: goal unreachable within 30 s: 100.00 m '
                                  'away, at most ')
    assert done.stderr.endswith('the horizon is at most 30 s: give a nearer goal; nothing '
                                'written\n')
    assert list(tmp_path.iterdir()) == []


def test_the_optimiser_stops_at_its_time_limit():
    model = IdealDiffDrive(0.42)
    planner = Planner(model, [], DriveTrain(max_speed=1.0),
                      CommandLimits(max_track_speed=1.0, max_track_accel=2.0))
    plan = planner.plan_to((2.0, 1.0, 0.5), 6.0, time_limit=1e-9)
    assert not plan.success
    assert plan.message.endswith('the optimiser was stopped at its time limit of 1e-09 s after '
                                 '0 predictions')
    assert np.all(np.abs(plan.commands) <= 1.0)   # still within the limits
    assert planner.plan_to((2.0, 1.0, 0.5), 6.0, time_limit=60.0).success


def test_the_time_limit_is_reported_by_the_command_line(tmp_path, capsys, monkeypatch):
    plan_to = Planner.plan_to

    def hurried(self, *args, **kwargs):
        assert kwargs['time_limit'] == 5.0   # --time-limit reaches the planner
        return plan_to(self, *args, **{**kwargs, 'time_limit': 1e-9})
    monkeypatch.setattr(Planner, 'plan_to', hurried)
    status, out, err = call(GOAL + ['--time-limit', '5', '--csv', tmp_path / 'p.csv'], capsys)
    assert status == 1 and out == ''
    assert 'the optimiser was stopped at its time limit of 1e-09 s after 0 predictions: give a ' \
        'larger --time-limit, a shorter --horizon or a nearer goal; nothing written' in err
    assert err.count('\n') == 1
    assert list(tmp_path.iterdir()) == []


def test_outputs_need_force_and_are_written_whole(tmp_path, capsys):
    csv_path, bag, plot = tmp_path / 'p.csv', tmp_path / 'bag', tmp_path / 'p.png'
    csv_path.write_text('mine\n')
    argv = GOAL + ['--csv', csv_path, '--bag', bag, '--plot', plot]
    status, _, err = call(argv, capsys)
    assert status == 2 and f'--csv {csv_path} exists; use --force to replace it' in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ['p.csv']
    status, out, err = call(argv + ['--force'], capsys)
    assert status == 0, err
    assert f'csv   {csv_path}' in out and f'bag   {bag} (' in out and f'plot  {plot}' in out
    assert csv_path.read_text().startswith('t,left,right,v_x,w,x,y,yaw\n')
    assert sorted(p.name for p in bag.iterdir()) == ['bag.db3', 'metadata.yaml']
    assert sorted(p.name for p in tmp_path.iterdir()) == ['bag', 'p.csv', 'p.png']
    status, _, err = call(argv + ['--force'], capsys)   # a bag is never replaced
    assert status == 2 and f'--bag {bag} exists; choose a new path for the bag' in err


@pytest.mark.parametrize('failure', ['plot', 'disk'])
def test_a_failure_late_in_the_run_leaves_nothing(tmp_path, capsys, monkeypatch, failure):
    from tracked_kinematics.offline import outputs, plots
    if failure == 'plot':
        def broken(path, *args):
            raise OSError(errno.ENOSPC, 'No space left on device')
        monkeypatch.setattr(plots, 'plot_plan', broken)
    else:
        real = outputs._fsync_file

        def broken(path):
            if path.name == 'metadata.yaml':
                raise OSError(errno.ENOSPC, 'No space left on device')
            real(path)
        monkeypatch.setattr(outputs, '_fsync_file', broken)
    status, _, err = call(GOAL + ['--csv', tmp_path / 'p.csv', '--bag', tmp_path / 'bag',
                                  '--plot', tmp_path / 'p.png'], capsys)
    assert status == 2 and err.endswith('No space left on device\n')
    assert list(tmp_path.iterdir()) == []


def test_outputs_are_refused_with_compare(capsys):
    status, _, err = call(['--compare', '--csv', 'p.csv'], capsys)
    assert status == 2 and err == 'plan_trajectory: error: --csv is not written with --compare\n'


def test_terrain_file_typos_are_named_and_bad_values_are_one_line(tmp_path, capsys):
    terrain = tmp_path / 't.yaml'
    terrain.write_text(TERRAIN.read_text() + '    scale_left: 1.0\n    max_track_sped: 1.0\n')
    status, _, err = call(['--params', terrain, '--goal', '1', '0', '0', '--horizon', '4'],
                          capsys)
    assert status == 0, err
    assert err.splitlines() == [
        f"plan_trajectory: warning: {terrain}: unknown parameter 'scale_left' is not used (did "
        "you mean 'scale.left'?)",
        f"plan_trajectory: warning: {terrain}: unknown parameter 'max_track_sped' is not used "
        "(did you mean 'max_track_speed'?)"]
    terrain.write_text('track_width: abc\n')
    status, _, err = call(['--params', terrain, '--goal', '1', '0', '0'], capsys)
    assert status == 2
    assert err == (f'plan_trajectory: error: {terrain}: track_width must be a number, got '
                   "'abc'\n")


DRIVE = SimpleNamespace(drivetrain=DriveTrain(max_accel=2.0, max_speed=1.5))


@pytest.mark.parametrize('values, expected', [
    ({}, {'max_track_speed': 1.5, 'max_track_accel': 2.0, 'max_track_decel': 2.0,
          'max_linear_velocity': math.inf}),
    # 0, NaN and inf are no limit, as for cmd_vel_translator (NaN was refused before).
    ({'max_track_speed': 0.0, 'linear.x.max_velocity': math.nan,
      'angular.z.max_velocity': math.inf},
     {'max_track_speed': math.inf, 'max_linear_velocity': math.inf,
      'max_angular_velocity': math.inf}),
    # A deceleration of either sign is its magnitude; 0 is the acceleration limit (it was
    # no limit, and a negative one was refused).
    ({'linear.x.max_acceleration': 1.0, 'linear.x.max_deceleration': -0.5,
      'angular.z.max_acceleration': 3.0, 'angular.z.max_deceleration': 0.0},
     {'max_linear_deceleration': 0.5, 'max_angular_deceleration': 3.0}),
])
def test_file_limits_mean_what_they_mean_to_the_translator(values, expected):
    limits = limits_from(values, DRIVE)
    assert limits == limits_from_values({'max_track_speed': 1.5, 'max_track_accel': 2.0,
                                         **values})
    assert {name: getattr(limits, name) for name in expected} == expected


def test_command_line_limits_win_and_a_deceleration_follows_them():
    limits = limits_from({'max_track_speed': 0.5, 'max_track_accel': 1.0}, DRIVE,
                         max_track_speed=0.8, max_track_accel=3.0)
    assert (limits.max_track_speed, limits.max_track_accel) == (0.8, 3.0)
    assert limits.max_track_decel == 3.0


@pytest.mark.parametrize('values, message', [
    ({'max_track_speed': -1.0}, 'max_track_speed must be >= 0'),
    ({'max_track_speed': 1e6}, 'max_track_speed must be in [0, '),
    ({'linear.x.max_acceleration': 'fast'}, 'linear.x.max_acceleration must be a number'),
])
def test_limits_the_translator_refuses_are_refused(tmp_path, capsys, values, message):
    with pytest.raises(UsageError, match=r'^t\.yaml: ' + re.escape(message)):
        limits_from(values, DRIVE, source='t.yaml')
    terrain = tmp_path / 't.yaml'
    name, value = next(iter(values.items()))
    terrain.write_text(TERRAIN.read_text() + f'    {name}: {value!r}\n')
    status, _, err = call(['--params', terrain, '--goal', '1', '0', '0', '--horizon', '4'],
                          capsys)
    assert status == 2 and err.startswith(f'plan_trajectory: error: {terrain}: {message}'), err


def test_a_bug_in_the_planner_is_a_traceback(capsys, monkeypatch):
    def bug(*args, **kwargs):
        raise ValueError('bug')
    monkeypatch.setattr(Planner, 'plan_to', bug)
    with pytest.raises(ValueError, match='^bug$'):
        plan_trajectory.main(GOAL)
    assert capsys.readouterr().err == ''


def test_a_terrain_file_of_another_vehicle_is_refused(tmp_path, capsys):
    # The Auriga's terrain file (0.42 m, 0.1 m) planned on the Packbot's drive train
    # (0.40 m, 0.085 m): before, a note with --plot only; now refused, nothing written.
    status, out, err = call(GOAL + ['--vehicle', 'packbot', '--csv', tmp_path / 'p.csv'],
                            capsys)
    assert status == 2 and out == ''
    assert err.count('\n') == 1 and err.startswith('plan_trajectory: error: track_width 0.42 m '
                                                   f'from {TERRAIN} and 0.4 m from --vehicle ')
    assert 'packbot.yaml differ by 5 %, more than rounding (1 %)' in err
    assert list(tmp_path.iterdir()) == []
    # The default vehicle is named as such: the user did not give it.
    warthog = tmp_path / 'warthog.yaml'
    warthog.write_text('track_width: 1.08\nsprocket_radius: 0.3\n')
    status, _, err = call(['--params', warthog, '--goal', '1', '0', '0'], capsys)
    assert status == 2
    assert err.startswith(f'plan_trajectory: error: track_width 1.08 m from {warthog} and '
                          '0.42 m from --vehicle auriga_alpha (the default: give --vehicle) ')
