"""
evaluate_model: score terrain models on recorded rosbags, from the encoders and the commands.

Reads the track encoders, a ground-truth pose and, where the bag has them, the commands
(per-track setpoints or cmd_vel), and scores each terrain file next to the ideal
differential drive of its track width: odometry from the encoders (final errors after
windows, drift, evo's relative pose error per 1 m and 10 m), predictions over a horizon from
the measured travel and from the commands through the file's drive train, and with
``--online`` the same for the icr_estimator's EKF replayed over the bags from each file.

The windows are those in which the vehicle moves (mean track speed at least
``--min-speed``, 0.1 m/s), so that a figure does not depend on how long the robot stood
still; ``--all-windows`` scores the idle ones too.

With ``--imu-topic`` instead of ``--ground-truth-topic`` the reference is the gyro: heading
only (its bias and delay behind the encoders estimated as identify_icr does); the position
figures are null in the report and ``-`` in the table, and there is no prediction from the
commands.

Exit status, as identify_icr: 0 success; 2 bad input (missing bag, topic or joint; unreadable
bag or terrain file; invalid option; an output that may not be written); 3 too little data
(no gap-free stretch of encoders and ground truth).

Documentation: docs/tools/evaluate_model.md (every figure of the report and how it is
computed).
"""

from __future__ import annotations

import argparse
from datetime import datetime, timezone
import json
import math
from pathlib import Path
import sys

import numpy as np
from tracked_kinematics.core import evaluate as ev
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.errors import ExcitationError, InvalidParameters
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.offline.bags import read_evaluation_bag
from tracked_kinematics.offline.bags.references import read_reference_bag
from tracked_kinematics.offline.cli.common import (
    add_command_arguments, add_ground_truth_arguments, add_vehicle_groups,
    add_window_selection_arguments, command_source, encoder_source, ground_truth_source,
    identification_parser, positive, require_vehicle, run_main)
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.outputs import Outputs
from tracked_kinematics.params import (
    drivetrain_from_values, icr_from_values, positive as check_positive, read_params_file,
    values_from_drivetrain)

PROG = 'evaluate_model'

EPILOG = """examples:
  evaluate_model run1/ run2/ --ground-truth-topic /mocap/pose --params hard_floor.yaml
  evaluate_model husky_wetgrass_part1 --ground-truth-topic /icp/pose \\
      --params husky_wetgrass.yaml --sprocket-radius 0.15875 --online \\
      --report eval.json --plot eval.png
  evaluate_model field.bag --ground-truth-topic /gps/odom --params grass.yaml gravel.yaml \\
      --window 2 5 10 30 --horizon 3 --command-source cmd_vel
  evaluate_model drive/ --imu-topic /imu/data --params grass.yaml   # heading only
"""


def build_parser() -> argparse.ArgumentParser:
    """Return the command line of evaluate_model."""
    parser = identification_parser(PROG, __doc__, EPILOG, ' (or --imu-topic)')
    parser.add_argument('--imu-topic', default=None, metavar='TOPIC',
                        help='instead of a ground-truth pose, a gyro (sensor_msgs/Imu): scores '
                        'heading only; the position figures are null')
    parser.add_argument('--params', nargs='+', required=True, metavar='A.yaml',
                        help='terrain files to score (each named by its file stem)')
    add_vehicle_groups(parser, positive, 'm, of the ideal drive and of the cmd_vel inverse; '
                       "default the first file's")
    gt = parser.add_argument_group('ground truth')
    add_ground_truth_arguments(gt)
    gt.add_argument('--keep-jumps', action='store_true',
                    help='score across ground-truth jumps (re-localisations, glitches: as '
                    'identify_icr finds them); by default they cut the data like gaps')
    cmd = parser.add_argument_group('commands')
    add_command_arguments(cmd)
    cmd.add_argument('--max-command-age', type=positive, default=0.5, metavar='SECONDS',
                     help='a command older than this is no longer in force')
    score = parser.add_argument_group('scores')
    score.add_argument('--window', type=positive, nargs='+', default=[5.0, 10.0],
                       metavar='SECONDS', help='odometry windows')
    add_window_selection_arguments(score)
    score.add_argument('--horizon', type=positive, default=2.0, metavar='SECONDS',
                       help='prediction horizon')
    score.add_argument('--prediction-dt', type=positive, default=0.05, metavar='SECONDS',
                       help='step of the predictions from the commands (DRIVE: 20 Hz)')
    score.add_argument('--rpe-distance', type=positive, nargs='+', default=[1.0, 10.0],
                       metavar='M', help='path lengths of the relative pose errors')
    score.add_argument('--online', action='store_true',
                       help='also replay the icr_estimator EKF over the bags from each file')
    out = parser.add_argument_group('output')
    out.add_argument('--report', default=None, metavar='OUT.json',
                     help='JSON report with every figure')
    out.add_argument('--plot', default=None, metavar='OUT.png',
                     help='error against window length, and paths')
    out.add_argument('--tum', default=None, metavar='DIR',
                     help='new directory: ground truth and odometry of each piece as TUM '
                     'trajectories, to check the RPE with evo_rpe')
    out.add_argument('--force', action='store_true', help='replace existing output files')
    return parser


# Inputs ----------------------------------------------------------------------------------


class _Model:
    """One terrain file: its values, ICR model and drive train."""

    def __init__(self, path: str):
        self.path = path
        self.values = read_params_file(path)
        # INTERFACE.md: the tread ICRs default to +-track_width/2 (ideal drive for the file's
        # width) unless set.
        width = self.values.get('track_width')
        if isinstance(width, (int, float)) and not isinstance(width, bool):
            self.values.setdefault('icr.y_left', 0.5 * width)
            self.values.setdefault('icr.y_right', -0.5 * width)
        try:
            self.icr = icr_from_values(self.values)
            self.drivetrain = drivetrain_from_values(self.values)
        except InvalidParameters as err:
            raise InvalidParameters(f'{path}: {err}') from None
        self.drivetrain_in_file = any(k.startswith('drivetrain.') for k in self.values)
        self.name = Path(path).stem


def _unique_names(models) -> None:
    """Name each file by its stem; a stem taken (``ideal``, twice the same) gets a suffix."""
    taken = {'ideal'}
    for model in models:
        name, n = model.name, 2
        while name in taken or f'online_{name}' in taken:
            name, n = f'{model.name}_{n}', n + 1
        model.name = name
        taken |= {name, f'online_{name}'}


def _vehicle(args, models):
    """Return the track width of the ideal drive and the sprocket radius."""
    first = models[0].values
    radius = args.sprocket_radius
    if radius is None:
        given = [m.values.get('sprocket_radius') for m in models]
        require_vehicle({'--sprocket-radius': None if None in given else 0.0},
                        'every terrain file')
        radii = {float(r) for r in given}
        if len(radii) > 1:
            raise UsageError('the terrain files disagree on sprocket_radius ('
                             f'{", ".join(f"{r:g}" for r in sorted(radii))} m): give '
                             '--sprocket-radius')
        radius = radii.pop()
    track_width = args.track_width
    if track_width is None:
        require_vehicle({'--track-width': first.get('track_width')}, 'the first terrain file')
        track_width = float(first['track_width'])
    for name, value in (('sprocket_radius', radius), ('track_width', track_width)):
        if check_positive(value):
            raise UsageError(f'{name} must be a finite number > 0, got {value!r}')
    return float(track_width), float(radius)


def _check_options(args) -> None:
    if bool(args.ground_truth_topic) == bool(args.imu_topic):
        raise UsageError('give --ground-truth-topic (a pose) or --imu-topic (a gyro, heading '
                         'only), one of them')
    if args.imu_topic and args.online:
        raise UsageError('--online needs --ground-truth-topic (the estimator uses poses)')
    if args.prediction_dt >= args.horizon:
        raise UsageError(f'--prediction-dt ({args.prediction_dt:g} s) must be shorter than '
                         f'--horizon ({args.horizon:g} s)')
    for flag, values in (('--window', args.window), ('--rpe-distance', args.rpe_distance)):
        if len(set(values)) != len(values):
            raise UsageError(f'{flag} lists a value twice: {" ".join(f"{v:g}" for v in values)}')


def _delays(args, recordings):
    """
    Return the ground-truth delay of each recording and a one-line account, as identify_icr.

    ``auto``: one delay for all bags (:func:`~tracked_kinematics.core.identify.
    estimate_delays`), or each bag's own when every bag determines its own; when the data do
    not time the ground truth, none is removed and the account says why.
    """
    if args.ground_truth_delay != 'auto':
        given = ident.fixed_delay(args.ground_truth_delay)
        return [given] * len(recordings), f'{given.delay:g} s (given)'
    pooled, each = ident.estimate_delays(recordings)
    if not pooled.determined:
        return [pooled] * len(recordings), (f'{pooled.describe()}; none removed: give it '
                                            'with --ground-truth-delay')
    if each:
        return each, 'per bag: ' + '; '.join(e.describe() for e in each)
    return [pooled] * len(recordings), pooled.describe()


def _read_imu(args, track_width, radius):
    """Read every bag with the gyro as a heading-only reference (bias and delay removed)."""
    encoders = encoder_source(args, radius)
    found = [read_reference_bag(bag, encoders, args.imu_topic, progress=sys.stderr.isatty())
             for bag in args.bags]
    try:
        gyro = ident.fit_recordings(found, track_width)
    except ExcitationError as err:
        raise ExcitationError(f'the gyro cannot be timed and de-biased: {err}') from None
    delay = gyro.imu_delay
    data, records = [], []
    for bag, rec, bias in zip(args.bags, found, gyro.biases):
        reference = ident.heading_reference(rec, delay.delay, bias)
        data.append(ev.Data(reference, None))
        records.append({
            'bag': str(Path(bag).resolve()), 'name': Path(bag).name,
            'duration_s': reference.duration, 'encoder_samples': len(rec.enc_t),
            'ground_truth_samples': 0, 'gyro_samples': len(rec.gyro_t),
            'gyro_bias_rad_s': float(bias), 'imu_delay_s': float(delay.delay),
            'ground_truth_delay_s': None, 'ground_truth_delay_std_s': None,
            'ground_truth_delay_source': None, 'commands': None, 'command_samples': 0})
    account = f'none (gyro reference); the gyro: {delay.describe()}'
    return data, records, account


def _heading_only(report) -> dict:
    """Null every position figure of a report scored against a gyro (they were not measured)."""
    for entry in report['models'].values():
        odo = entry['odometry']
        for win in odo['windows'].values():
            for key in ('mean_position_error_m', 'p90_position_error_m', 'mean_distance_m',
                        'drift_pct'):
                win[key] = None
        odo['drift_pct'] = None
        for key in list(odo['horizon']):
            if 'translation' in key:
                odo['horizon'][key] = None
        for key in list(entry):
            if key.startswith('rpe_'):
                entry[key] = None
        entry['rpe'] = None
        entry['prediction'] = None
    for piece in report['pieces']:
        piece['path_length_m'] = None
    report['reference'] = 'imu'
    report['scored'] = 'heading only: the gyro measures no position'
    return report


def _read(args, track_width, radius):
    """Read every bag; return recordings (delay taken off), their commands, records, delay."""
    if args.imu_topic:
        return _read_imu(args, track_width, radius)
    encoders = encoder_source(args, radius)
    ground_truth = ground_truth_source(args)
    commands = command_source(args, track_width)
    progress = sys.stderr.isatty()
    found = [read_evaluation_bag(bag, encoders, ground_truth, commands, progress)
             for bag in args.bags]
    recordings = [recording for recording, _ in found]
    delays, account = _delays(args, recordings)
    data, records = [], []
    for bag, (recording, cmds), delay in zip(args.bags, found, delays):
        if cmds is not None:
            cmds = ev.Commands(*cmds)
        data.append(ev.Data(ident.correct_ground_truth([recording], delay.delay)[0], cmds))
        records.append({
            'bag': str(Path(bag).resolve()), 'name': Path(bag).name,
            'duration_s': recording.duration, 'encoder_samples': len(recording.enc_t),
            'ground_truth_samples': len(recording.gt_t),
            'ground_truth_delay_s': float(delay.delay),
            'ground_truth_delay_std_s': None if delay.uncertainty == 'given'
            else float(delay.std),
            'ground_truth_delay_source': 'given' if delay.uncertainty == 'given'
            else ('auto' if delay.determined else 'not determined'),
            'commands': None if cmds is None else cmds.source,
            'command_samples': 0 if cmds is None else len(cmds.t)})
    return data, records, account


# Outputs ---------------------------------------------------------------------------------


def _icr_summary(icr: IcrParams) -> dict:
    return {'track_width': icr.track_width, 'y_left': icr.y_left, 'y_right': icr.y_right,
            'x': icr.x, 'scale_left': icr.scale_left, 'scale_right': icr.scale_right,
            'chi': icr.chi, 'eccentricity': icr.eccentricity}


def _finite(value):
    """JSON without NaN or inf: non-finite floats become null, numpy values plain ones."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, (np.floating, float)):
        value = float(value)
        return value if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def _fmt(value, scale=1.0, digits=3) -> str:
    return '-' if value is None else f'{scale * value:.{digits}f}'


def _print_table(report, out) -> None:
    recs = report['recordings']
    cut = report['data']
    jumps = ('kept' if report['settings']['keep_jumps']
             else f'{cut["jumps"]} ground-truth jumps left out')
    print(f'{PROG}: {len(recs)} bag(s), {sum(r["duration_s"] for r in recs):.0f} s; scored '
          f'{cut["seconds"]:.0f} s in {cut["pieces"]} gap-free pieces ({cut["gaps"]} gaps, '
          f'{jumps})', file=out)
    print(f'ground-truth delay behind the encoders: {report["ground_truth_delay"]}', file=out)
    if report.get('reference') == 'imu':
        print('reference: the gyro, heading only: position figures are not scored (null in '
              'the report, - below)', file=out)
    sources = sorted({r['commands'] for r in recs if r['commands']})
    if not sources:
        print('no commands in the bags: no prediction from commands', file=out)
    settings = report['settings']
    windows = [ev.window_key(w) for w in settings['windows_s']]
    deltas = [ev.rpe_key(d) for d in settings['rpe_distances_m']]
    horizon = f'{settings["horizon_s"]:g} s'
    head = f'{"model":<26}'
    for w in windows:
        head += f'{w + " s: pos m":>13}{"hdg deg":>9}'
    head += f'{"drift %":>9}'
    for d in deltas:
        head += f'{"RPE " + d.replace("m", " m"):>10}'
    head += f'{horizon + " enc: m":>14}{"deg":>7}'
    if sources:
        head += f'{horizon + " cmd: m":>14}{"deg":>7}'
    print('\nerrors: window means (p90 and more in the report); RPE: RMSE of the translation '
          f'part; {horizon} predictions: mean RMSE over the horizon', file=out)
    print(head, file=out)
    for name, m in report['models'].items():
        odo = m['odometry']
        row = f'{name:<26}'
        for w in windows:
            win = odo['windows'][w]
            row += f'{_fmt(win["mean_position_error_m"]):>13}'
            row += f'{_fmt(win["mean_heading_error_rad"], 180 / math.pi, 2):>9}'
        row += f'{_fmt(odo["drift_pct"], digits=1):>9}'
        for d in deltas:
            row += f'{_fmt(m[f"rpe_{d}"]):>10}'
        hor = odo['horizon']
        row += f'{_fmt(hor["mean_rmse_translation_m"]):>14}'
        row += f'{_fmt(hor["mean_rmse_rotation_rad"], 180 / math.pi, 2):>7}'
        if sources:
            pred = m['prediction'] or {}
            row += f'{_fmt(pred.get("mean_rmse_translation_m")):>14}'
            row += f'{_fmt(pred.get("mean_rmse_rotation_rad"), 180 / math.pi, 2):>7}'
        print(row.rstrip(), file=out)
    ideal = report['models']['ideal']['odometry']['windows']
    selection = report['windows_selection']
    if selection['moving_only']:
        counts = (f'windows in which the tracks move (mean track speed >= '
                  f'{selection["min_speed_mps"]:g} m/s; --all-windows for all): '
                  + ', '.join(f'{ideal[w]["n"]} of {ideal[w]["n_total"]} of {w} s'
                              for w in windows))
    else:
        counts = 'windows, idle ones too: ' + ', '.join(f'{ideal[w]["n"]} of {w} s'
                                                        for w in windows)
    print(counts
          + f'; {report["models"]["ideal"]["odometry"]["horizon"]["n"]} horizons from the '
          'encoders' + (f', {(report["models"]["ideal"]["prediction"] or {}).get("n", 0)} from '
                        'the commands' if sources else ''), file=out)
    for name, m in report['models'].items():
        online = m.get('online')
        if online:
            outcomes = online['outcomes']
            print(f'{name}: {outcomes.get("updated", 0)} updates, {outcomes.get("outlier", 0)} '
                  f'poses refused as jumps, {outcomes.get("anchored", 0)} re-anchors; model '
                  f'error {math.sqrt(online["noise_scale"]):.1f} x travel_std; its own '
                  f'estimate in use {100 * online["trusted_fraction"]:.0f} % of the time '
                  "(else the file's values)", file=out)


def _report(args, models, records, account, evaluation, candidates, runs, track_width,
            radius):
    settings = {'windows_s': [float(w) for w in args.window], 'horizon_s': args.horizon,
                'prediction_dt_s': args.prediction_dt,
                'rpe_distances_m': [float(d) for d in args.rpe_distance],
                'max_command_age_s': args.max_command_age,
                'keep_jumps': args.keep_jumps,
                'track_width': track_width, 'sprocket_radius': radius,
                'command_source': args.command_source}
    for record, c in zip(records, evaluation.cuts):
        record.update({'pieces': len(c.pieces), 'seconds_in_pieces': c.seconds,
                       'gaps': c.gaps, 'jumps': c.jumps})
    entries = {}
    by_name = {m.name: m for m in models}
    for candidate in candidates:
        entry = {}
        if candidate.name == 'ideal':
            entry.update({'kind': 'ideal', 'file': None, 'icr': _icr_summary(candidate.icr),
                          'drivetrain': None})
        else:
            online = candidate.runs is not None
            model = by_name[candidate.name[len('online_'):] if online else candidate.name]
            entry.update({'kind': 'online' if online else 'file',
                          'file': str(Path(model.path).resolve()),
                          'icr': _icr_summary(model.icr),
                          'drivetrain': {**values_from_drivetrain(model.drivetrain),
                                         'from_file': model.drivetrain_in_file}})
            if online:
                rs = runs[model.name]
                outcomes = {}
                for r in rs:
                    for k, v in r.outcomes.items():
                        outcomes[k] = outcomes.get(k, 0) + v
                entry['online'] = {
                    'model': 'icr', 'start': model.name, 'outcomes': outcomes,
                    'noise_scale': float(max(r.noise_scale for r in rs)),
                    'trusted_fraction': float(np.mean([r.trusted for r in rs])),
                    'final_icr': [r.icr[-1].tolist() for r in rs]}
        entry.update(evaluation.models[candidate.name])
        entries[candidate.name] = entry
    cuts = evaluation.cuts
    return {
        'tool': PROG, 'date': datetime.now(timezone.utc).isoformat(timespec='seconds'),
        'bags': [r['bag'] for r in records], 'settings': settings, 'recordings': records,
        'ground_truth_delay': account,
        'windows_selection': {'moving_only': not args.all_windows,
                              'min_speed_mps': None if args.all_windows else args.min_speed},
        'data': {'pieces': sum(len(c.pieces) for c in cuts), 'gaps': sum(c.gaps for c in cuts),
                 'jumps': sum(c.jumps for c in cuts),
                 'seconds': float(sum(c.seconds for c in cuts))},
        'pieces': [{'piece': k, 'bag': records[p.recording]['bag'], 't_start_s': float(p.t[0]),
                    't_end_s': float(p.t[-1]), 'samples': len(p.t),
                    'path_length_m': p.path_length}
                   for k, p in enumerate(evaluation.pieces)],
        'order': [c.name for c in candidates], 'models': entries,
    }


def _write_tum(directory: Path, evaluation, names) -> None:
    """
    Write each piece's ground truth and odometry as TUM trajectories (``t x y z qx qy qz qw``).

    ``piece007.ground_truth.tum`` and ``piece007.<model>.tum``: the same times, so that
    ``evo_rpe tum piece007.ground_truth.tum piece007.<model>.tum --delta 1 --delta_unit m``
    finds the report's ``rpe.1m.pieces`` entry of piece 7.
    """
    directory.mkdir()
    for k, piece in enumerate(evaluation.pieces):
        paths = {'ground_truth': piece.truth,
                 **{name: evaluation.paths[name][k] for name in names}}
        for name, path in paths.items():
            half = 0.5 * path[:, 2]
            rows = np.column_stack([piece.t, path[:, 0], path[:, 1], np.zeros(len(path)),
                                    np.zeros(len(path)), np.zeros(len(path)), np.sin(half),
                                    np.cos(half)])
            np.savetxt(directory / f'piece{k:03d}.{name}.tum', rows, fmt='%.9f')


# Main ----------------------------------------------------------------------------------


def _run(args, out) -> int:
    _check_options(args)
    from tracked_kinematics.offline.evaluation_plot import check_format, plot_evaluation
    fmt = check_format(args.plot) if args.plot else None
    with Outputs(force=args.force) as outputs:
        outputs.add('--report', args.report)
        outputs.add('--plot', args.plot)
        outputs.add('--tum', args.tum, directory=True)
        models = [_Model(path) for path in args.params]
        _unique_names(models)
        track_width, radius = _vehicle(args, models)
        data, records, account = _read(args, track_width, radius)
        candidates = [ev.Candidate('ideal', IcrParams.ideal(track_width), None)]
        candidates += [ev.Candidate(m.name, m.icr, m.drivetrain) for m in models]
        runs = {}
        if args.online:
            for m in models:
                runs[m.name] = tuple(ev.replay(d.recording, m.icr, r['ground_truth_delay_s'])
                                     for d, r in zip(data, records))
                candidates.append(ev.Candidate(f'online_{m.name}', m.icr, m.drivetrain,
                                               runs[m.name]))
        settings = ev.Settings(tuple(args.window), args.horizon, args.prediction_dt,
                               tuple(args.rpe_distance), args.max_command_age,
                               not args.keep_jumps, track_width,
                               None if args.all_windows else args.min_speed)
        evaluation = ev.evaluate(data, candidates, settings)
        if not evaluation.pieces:
            raise ExcitationError('no stretch of the bags has both encoders and ground truth '
                                  'without a gap: nothing to score')
        report = _finite(_report(args, models, records, account, evaluation, candidates, runs,
                                 track_width, radius))
        if args.imu_topic:
            report = _heading_only(report)
        _print_table(report, out)
        if args.report:
            outputs.write_text('--report', json.dumps(report, indent=2, allow_nan=False)
                               + '\n')
        if args.tum:
            with outputs.path('--tum') as tmp:
                _write_tum(tmp, evaluation, [c.name for c in candidates])
        if args.plot:
            with outputs.path('--plot') as tmp:
                plot_evaluation(tmp, evaluation, [c.name for c in candidates],
                                tuple(args.window), fmt=fmt,
                                min_speed=settings.min_speed)
    written = [p for p in (args.report, args.plot, args.tum) if p]
    if written:
        print(f'wrote {", ".join(written)}', file=out)
    return 0


def main(argv=None) -> int:
    """Run evaluate_model; return the exit status (see the module docstring)."""
    return run_main(PROG, _run, build_parser().parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
