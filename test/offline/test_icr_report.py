"""offline.identification: identify_icr as a library, recordings in, what to write out (no CLI)."""

import json

from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core.identify import Recording
from tracked_kinematics.core.identify.procedure import IdentifyOptions, MIN_SPEED
from tracked_kinematics.core.models import ConstantIcr, EffectiveWheelBase
from tracked_kinematics.offline.identification import (
    FitOptions, FitResult, icr_from_poses, icr_from_references, TOOL)
from tracked_kinematics.params import icr_from_values

DATE = '2026-01-02T03:04:05+00:00'


def options(bags, *, terrain=None, model='icr_scales', spin=False, **identify):
    """Return identify_icr's options: its defaults but those given."""
    return FitOptions(tuple(bags), terrain=terrain, model=model, spin_in_place=spin,
                      identify=IdentifyOptions(**{'ground_truth_delay': 'auto', **identify}))


def strict(report):
    """Return the report through JSON: no NaN, no infinity (the report is for machines)."""
    text = json.dumps(report, allow_nan=False,
                      default=lambda o: o.tolist() if isinstance(o, np.ndarray) else float(o))
    return json.loads(text)


@pytest.fixture(scope='module')
def standing():
    """Four minutes of the Auriga-alpha that stands still 25 s of every 40 s."""
    return simulate(ConstantIcr(B), np.array(AURIGA), duration=240.0, enc_rate=50.0, seed=5,
                    stand=(40.0, 25.0))


@pytest.fixture(scope='module')
def moving_only(standing):
    return icr_from_poses([standing], options(['/data/standing'], terrain='floor',
                                              ground_truth_delay=0.0), B, 0.1, date=DATE)


def test_pose_fit_returns_the_values_the_report_and_the_table(moving_only):
    found = moving_only
    assert isinstance(found, FitResult) and found.date == DATE
    values = found.values
    icr = icr_from_values(values)   # a terrain file odometry_node loads
    np.testing.assert_allclose([icr.y_left, icr.y_right, icr.x], AURIGA[:3], atol=1e-3)
    assert values['terrain'] == 'floor' and values['sprocket_radius'] == 0.1
    assert values['identification.model'] == 'icr_scales'
    assert values['identification.date'] == DATE
    assert values['identification.bags'] == ['/data/standing']
    assert values['identification.holdout_windows'] == 'moving'
    assert values['identification.holdout_min_speed'] == MIN_SPEED
    assert found.note == ''
    doc = strict(found.report)
    assert doc['tool'] == TOOL and doc['mode'] == 'segments' and doc['date'] == DATE
    assert doc['icr']['y_left'] == pytest.approx(AURIGA[0], abs=1e-3)
    assert doc['windows_selection'] == {'moving_only': True, 'min_speed_mps': MIN_SPEED}
    lines = found.lines
    assert lines[0].startswith(f'{TOOL}: 1 bag(s): ')
    assert lines[1] == 'ground-truth delay behind the encoders: off (--ground-truth-delay 0)'
    assert any(line.startswith('\nhold-out: ') for line in lines)
    assert found.text == '\n'.join(lines) and not found.text.endswith('\n')
    assert 'diff_drive_controller:\n  ros__parameters:' in found.text
    # The fit itself, for the plot.
    assert found.identification.icr == pytest.approx(icr)


def test_holdout_scores_the_windows_in_which_the_vehicle_moves(standing, moving_only):
    every = icr_from_poses([standing], options(['/data/standing'], ground_truth_delay=0.0,
                                               min_speed=None), B, 0.1, date=DATE)
    moving = moving_only.report['holdout']['models']['ideal']['windows']
    idle_too = every.report['holdout']['models']['ideal']['windows']
    # The same windows before the selection; idle ones are most of them here.
    assert moving['n_total'] == idle_too['n_total'] == idle_too['n']
    assert 0 < moving['n'] < 0.7 * moving['n_total']
    assert moving_only.report['holdout']['windows'] == moving['n']
    # A window in which the robot stands costs ideal drive nothing: over all windows its error
    # reads less than half of what it is while the robot drives.
    assert idle_too['position_mean'] < 0.6 * moving['position_mean']
    assert every.report['windows_selection'] == {'moving_only': False, 'min_speed_mps': None}
    assert every.values['identification.holdout_windows'] == 'all'
    assert 'identification.holdout_min_speed' not in every.values
    said = [next(line for line in r.lines if 'hold-out:' in line) for r in (moving_only, every)]
    assert (f'{moving["n"]} of {moving["n_total"]} windows of 10 s, those in which the tracks '
            'move (mean track speed >= 0.1 m/s; --all-windows for all)') in said[0]
    assert f'{idle_too["n"]} windows of 10 s, idle ones too' in said[1]
    # The fit is the same either way: only the scoring differs.
    assert every.values['icr.y_left'] == moving_only.values['icr.y_left']


def test_a_higher_min_speed_keeps_fewer_windows(standing, moving_only):
    fast = icr_from_poses([standing], options(['b'], ground_truth_delay=0.0, min_speed=0.5,
                                              holdout=0.2), B, 0.1, date=DATE)
    kept = fast.report['holdout']['models']['ideal']['windows']
    assert kept['n'] < moving_only.report['holdout']['models']['ideal']['windows']['n']
    assert fast.values['identification.holdout_min_speed'] == 0.5


def test_no_window_that_fast_is_said_as_such(standing):
    # Windows there are; none of them moves at 20 m/s: the line says that, not "too short".
    none = icr_from_poses([standing], options(['b'], ground_truth_delay=0.0, min_speed=20.0),
                          B, 0.1, date=DATE)
    kept = none.report['holdout']['models']['ideal']['windows']
    assert kept['n'] == 0 and kept['n_total'] > 0
    said = next(line for line in none.lines if 'hold-out:' in line)
    assert (f'none of {kept["n_total"]} held-out windows of 10 s in which the tracks move '
            '(mean track speed >= 20 m/s; a lower --min-speed or --all-windows scores some)'
            ) in said
    strict(none.report)


def test_models_without_constant_icrs_say_where_the_icrs_come_from(standing):
    found = icr_from_poses([standing], options(['b'], model='general_slip',
                                               ground_truth_delay=0.0, holdout=0.0), B, 0.1)
    assert found.values['identification.icr_source'] == 'icr_scales'
    assert 'the general_slip parameters are under identification.parameters' in found.note
    assert found.report['holdout'] is None
    assert 'hold-out: none (--holdout 0)' in found.lines
    # No hold-out figures, so no word on which windows they are over.
    assert not any(k.startswith('identification.holdout') for k in found.values)


def test_spin_in_place_runs():
    rec = simulate(EffectiveWheelBase(B), [0.526], duration=40.0, enc_rate=50.0, seed=2,
                   legs=('spin',))
    found = icr_from_poses([rec], options(['spins'], spin=True, ground_truth_delay=0.0), B,
                           0.1, tool='my_tool')
    assert found.identification is None
    assert found.report['mode'] == 'spin_in_place' and found.report['tool'] == 'my_tool'
    assert found.report['chi'] == pytest.approx(0.526, abs=1e-3)
    assert found.values['identification.model'] == 'spin_in_place'
    assert found.lines[-1].startswith('my_tool: ') and 'chi = 0.5260' in found.lines[-1]


def test_reference_calibration_from_a_gyro(standing):
    # An ideal orientation estimate (the simulated yaw) as the heading reference.
    gyro = Recording(standing.enc_t, standing.left, standing.right,
                     gyro_t=standing.gt_t, gyro_yaw=standing.gt_yaw, name='gyro')
    found = icr_from_references([gyro], options(['/data/gyro'], terrain='floor'), B, 0.1,
                                date=DATE)
    values = found.values
    icr_from_values(values)
    assert values['identification.method'] == 'reference'
    assert values['identification.reference'] == 'imu'
    assert 'chi' in values['identification.determined']
    # chi = B / (y_left - y_right), within the scales the gyro cannot tell from it.
    assert values['identification.chi'] == pytest.approx(B / (AURIGA[0] - AURIGA[1]),
                                                         rel=0.03)
    assert found.note.startswith('Calibrated without ground truth (imu): held, not fitted: ')
    doc = strict(found.report)
    assert doc['mode'] == 'reference' and doc['recordings'][0]['gyro_samples'] == len(
        standing.gt_t)
    assert found.identification is None
    assert found.lines[0].startswith(f'{TOOL}: 1 bag(s), reference imu: ')
    assert any(line.startswith('held (--params or ideal drive): distance_scale: ')
               for line in found.lines)
