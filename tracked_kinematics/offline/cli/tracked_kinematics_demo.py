"""
The out-of-the-box demo: simulate, identify, and compare odometry on held-out paths.

Four steps, each the code path a user would run:

1. simulate a tracked robot driving on a terrain (the stationary track-soil model of
   Martinez et al. 2005, sec. 4.1, a drive train, quantised and noisy encoders, a noisy
   ground truth) and record a calibration bag (:func:`.simulate_bag.simulate_bag`);
2. fit that bag as ``identify_icr`` does (:func:`tracked_kinematics.offline.identification.
   fit`, what the console script calls), and write its terrain YAML, JSON report and plot;
3. simulate held-out paths (other seeds, not used by the fit), record them as bags, read
   their ``/joint_states`` back and dead-reckon them twice: as ``diff_drive_controller``
   does (ideal differential drive, ICRs on the track centrelines, no scale corrections)
   and through the identified ICRs loaded back from the written YAML (Martinez eqs. 7-9,
   20-21); compare the final poses with the simulator's true poses;
4. say where every output is, how to score the fit with ``evaluate_model`` and how to use
   the YAML with ``odometry_node`` (the console scripts of a venv; ``ros2 run`` in a
   workspace).

Its output directory holds a manifest (``.tracked_kinematics_demo``, JSON) of exactly the
files, bags and directories the demo created there (:mod:`..demo_directory`). A rerun
removes what the manifest lists and nothing else (never following a symbolic link), so
``make demo`` twice works without ``--force``; any other file in the way is replaced only
with ``--force`` (a bag or a directory never). A failed or interrupted run removes what it
wrote.

Exit status: 0 success; 2 bad input or an output that may not be written; identify_icr's
status (3, 4) when the calibration drive cannot be identified; 130 / 143 interrupted.

Documentation: docs/tools/tracked_kinematics_demo.md; the model: docs/model.md.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
from dataclasses import dataclass
import io
import math
from pathlib import Path
import shlex
import sys
import textwrap
import time

import numpy as np
from tracked_kinematics.core.gyro import GyroConfig, replay
from tracked_kinematics.core.integration import wrap_angle
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import ConstantIcr
from tracked_kinematics.core.recording import Recording
from tracked_kinematics.core.sim.sensors import GyroModel
from tracked_kinematics.core.sim.simulation import TwistTable
from tracked_kinematics.offline.bag_simulation import (
    GROUND_TRUTH_TOPICS, IMU_TOPIC, JOINTS, simulate_bag)
from tracked_kinematics.offline.bags import EncoderSource, GroundTruthSource, read_recording
from tracked_kinematics.offline.cli.common import (
    add_force_argument, add_plot_output, ArgumentParser, bounded, run_main, SEED,
    write_together)
from tracked_kinematics.offline.demo_directory import (bag_files, DemoDirectory, DemoError,
                                                       Entry, planned_outputs)
from tracked_kinematics.offline.identification import (
    fit, FitOptions, TOOL as FIT_TOOL, write_fit)
from tracked_kinematics.offline.outputs import Outputs
from tracked_kinematics.offline.vehicle_file import (
    add_vehicle_arguments, fixed, load_vehicle, overrides_from_args)
from tracked_kinematics.params import gyro_config_from_values, icr_from_values, read_params_file

PROG = 'tracked_kinematics_demo'
HELDOUT_MANOEUVRES = ('random', 'sweep', 'random', 'mixed', 'random')
"""Manoeuvre set of held-out path k (cycled)."""
GT_TOPIC = GROUND_TRUTH_TOPICS['pose']
GYRO = GyroModel(rate=100.0, bias=0.01, noise_std=0.003, latency=0.05, scale=1.02)
"""The demo robot's gyro: biased, noisy, 2 % over-reading, stamped 0.05 s late."""


@dataclass(frozen=True)
class PathResult:
    """
    Odometry errors of one held-out path.

    Attributes
    ----------
    name : str
        Path name (also its bag's directory name).
    manoeuvres : str
        Manoeuvre set it was drawn from.
    seed : int
        Its simulation seed.
    duration, distance : float
        Length of the path, s and m (true path).
    truth, ideal, identified : ndarray, shape (N, 3)
        True pose and the two dead reckonings at each encoder sample.
    gyro_aided : ndarray, shape (N, 3)
        The identified ICRs with the gyro's heading (odometry_node with ``imu_topic``).
    recording : Recording or None
        Its bag as read (encoders, ground truth, gyro), for the covariance check.

    """

    name: str
    manoeuvres: str
    seed: int
    duration: float
    distance: float
    truth: np.ndarray
    ideal: np.ndarray
    identified: np.ndarray
    gyro_aided: np.ndarray
    recording: Recording | None = None

    def errors(self, which: str) -> tuple[float, float, float]:
        """
        Compute the final errors of a dead reckoning against the true pose.

        Parameters
        ----------
        which : {'ideal', 'identified', 'gyro_aided'}
            The dead reckoning.

        Returns
        -------
        position, heading, percent : float
            Final position error (m), absolute final heading error (deg), and the position
            error as a percentage of the distance travelled.

        """
        odo = getattr(self, which)
        position = float(np.hypot(*(odo[-1, :2] - self.truth[-1, :2])))
        heading = math.degrees(abs(float(wrap_angle(odo[-1, 2] - self.truth[-1, 2]))))
        return position, heading, 100.0 * position / max(self.distance, 1e-9)


def dead_reckon(icr: IcrParams, left, right) -> np.ndarray:
    """
    Dead-reckon cumulative nominal track travel through constant tread ICRs, from pose zero.

    Vectorised over the whole log: the scales correct the travel (Martinez eqs. 20-21), the
    ICRs map it to body increments (eqs. 7-9) and the pose follows exact arcs
    (:func:`tracked_kinematics.core.integration.integrate`), the same steps
    :class:`tracked_kinematics.core.odometry.Odometry` takes one message at a time.
    ``IcrParams.ideal(track_width)`` gives ``diff_drive_controller``'s odometry.

    Parameters
    ----------
    icr : IcrParams
        Kinematic model.
    left, right : array_like, shape (N,)
        Cumulative nominal travel of each track at the encoder samples, m.

    Returns
    -------
    ndarray, shape (N, 3)
        Pose ``(x, y, theta)`` at each sample, the first one zero; theta continuous.

    """
    model = ConstantIcr(icr.track_width)
    x, y, theta = model.integrate(model.from_icr(icr), np.diff(left), np.diff(right), 1.0)
    return np.column_stack([np.r_[0.0, x], np.r_[0.0, y], np.r_[0.0, theta]])


# Steps -----------------------------------------------------------------------------------


def identify(bag: Path, out: Path, terrain: str, track_width: float, radius: float,
             force: bool = False):
    """
    Fit the calibration bag as ``identify_icr`` would: its fit, its outputs, its statuses.

    Returns
    -------
    status : int
        Its exit status.
    command : list of str
        The equivalent command line.
    output : str
        What it printed on stdout.

    """
    options = FitOptions(bags=(str(bag),), track_width=track_width, sprocket_radius=radius,
                         ground_truth=GroundTruthSource(GT_TOPIC), terrain=terrain)
    paths = {'--output': out / f'{terrain}.yaml', '--report': out / 'identify_report.json',
             '--plot': out / 'identify.png'}
    argv = [str(bag), '--ground-truth-topic', GT_TOPIC, '--output', str(paths['--output']),
            '--sprocket-radius', repr(radius), '--track-width', repr(track_width),
            '--terrain', terrain, '--report', str(paths['--report']),
            '--plot', str(paths['--plot'])] + (['--force'] if force else [])

    def run(_, printed) -> int:
        outputs = Outputs(force=force)
        outputs.add('--output', paths['--output'])
        outputs.add('--report', paths['--report'])
        add_plot_output(outputs, paths['--plot'])
        outputs.refuse_inputs('BAG', [bag])

        def work(outputs):
            # The bag's gyro is found by the pose fit itself: imu_delay and gyro_scale.
            found = fit(options)
            print(found.text, file=printed)
            write_fit(found, outputs, options)
        return write_together(outputs, work, printed)

    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        status = run_main(FIT_TOOL, run, None)
    return status, [FIT_TOOL] + argv, buffer.getvalue()


def heldout_name(k: int) -> str:
    """Name of held-out path ``k`` (from 0) and of its bag."""
    return f'path{k + 1}_{HELDOUT_MANOEUVRES[k % len(HELDOUT_MANOEUVRES)]}'


def heldout_path(k: int, args, overrides, table, identified: IcrParams,
                 directory: Path, gyro: GyroConfig | None = None) -> PathResult:
    """Simulate held-out path ``k``, record it, read it back and dead-reckon it."""
    manoeuvres = HELDOUT_MANOEUVRES[k % len(HELDOUT_MANOEUVRES)]
    seed = args.seed + 1 + k
    name = heldout_name(k)
    sim = simulate_bag(directory / name, args.vehicle, overrides=overrides,
                       manoeuvres=manoeuvres, duration=args.path_duration, seed=seed,
                       storage=args.storage, table=table,
                       force=bool(getattr(args, 'force', False)), parents=False,
                       imu=GYRO)
    radius = sim.vehicle.robot.encoders.sprocket_radius
    rec = read_recording(sim.bag, EncoderSource(left_joints=JOINTS[:1], right_joints=JOINTS[1:],
                                                sprocket_radius=radius),
                         imu_topic=IMU_TOPIC, ground_truth=GroundTruthSource(GT_TOPIC))
    run = sim.run
    if len(rec.enc_t) != len(run.t):
        raise RuntimeError(f'{sim.bag}: read {len(rec.enc_t)} encoder samples, wrote '
                           f'{len(run.t)}')
    ideal = IcrParams.ideal(identified.track_width)
    aided, _, _ = replay(rec.enc_t, rec.left, rec.right, rec.gyro_t, rec.gyro_rate, identified,
                         gyro, published_at=np.zeros(len(rec.enc_t), dtype=bool))
    return PathResult(name, manoeuvres, seed, run.duration, run.distance, run.pose,
                      dead_reckon(ideal, rec.left, rec.right),
                      dead_reckon(identified, rec.left, rec.right), aided, rec)


def print_table(results, out) -> tuple[float, float]:
    """
    Print the held-out error table and its means.

    Returns
    -------
    position, heading : float
        Improvement of the identified model over ideal drive in the mean final position and
        heading errors, %.

    """
    print(f'   {"":<18}{"":>16}  {"ideal differential drive":^26}  '
          f'{"identified ICRs":^26}'.rstrip(), file=out)
    print(f'   {"path":<18}{"dist (m)":>8}{"time (s)":>9}  {"pos (m)":>8}{"head (deg)":>11}'
          f'{"% dist":>8}  {"pos (m)":>8}{"head (deg)":>11}{"% dist":>8}', file=out)

    def row(label, distance, duration, ideal, ident):
        print(f'   {label:<18}{distance:>8.1f}{duration:>9.0f}  {ideal[0]:>8.3f}{ideal[1]:>11.1f}'
              f'{ideal[2]:>8.1f}  {ident[0]:>8.3f}{ident[1]:>11.1f}{ident[2]:>8.1f}', file=out)

    ideal = np.array([r.errors('ideal') for r in results])
    ident = np.array([r.errors('identified') for r in results])
    for r, i, d in zip(results, ideal, ident):
        row(r.name, r.distance, r.duration, i, d)
    row('mean', np.mean([r.distance for r in results]),
        np.mean([r.duration for r in results]), ideal.mean(axis=0), ident.mean(axis=0))
    mean_ideal, mean_ident = ideal.mean(axis=0), ident.mean(axis=0)
    gains = 100.0 * (1.0 - mean_ident[:2] / np.maximum(mean_ideal[:2], 1e-12))
    print(f'   identified ICRs vs ideal: final position error {-gains[0]:+.0f} %, '
          f'heading error {-gains[1]:+.0f} %', file=out)
    aided = np.array([r.errors('gyro_aided') for r in results])
    print('   gyro-aided (the identified ICRs, the heading from the gyro as odometry_node with '
          'imu_topic):', file=out)
    print('   ' + ', '.join(f'{r.name} {a[0]:.3f} m {a[1]:.1f} deg' for r, a in
                            zip(results, aided)), file=out)
    mean_aided = aided.mean(axis=0)
    print(f'   mean {mean_aided[0]:.3f} m, {mean_aided[1]:.1f} deg ({mean_aided[2]:.1f} % of '
          f'the distance) against {mean_ident[0]:.3f} m, {mean_ident[1]:.1f} deg from the '
          'encoders alone', file=out)
    return float(gains[0]), float(gains[1])


def csv_text(results) -> str:
    """Return the held-out errors as CSV, one row per path."""
    stream = io.StringIO(newline='')
    writer = csv.writer(stream)
    writer.writerow(['path', 'manoeuvres', 'seed', 'duration_s', 'distance_m',
                     'ideal_position_error_m', 'ideal_heading_error_deg',
                     'ideal_error_pct_of_distance', 'identified_position_error_m',
                     'identified_heading_error_deg', 'identified_error_pct_of_distance',
                     'gyro_aided_position_error_m', 'gyro_aided_heading_error_deg',
                     'gyro_aided_error_pct_of_distance'])
    for r in results:
        writer.writerow([r.name, r.manoeuvres, r.seed, f'{r.duration:.2f}',
                         f'{r.distance:.4f}']
                        + [f'{v:.6g}' for v in r.errors('ideal') + r.errors('identified')
                           + r.errors('gyro_aided')])
    return stream.getvalue()


# Command line ----------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    """Return the command line of the demo."""
    parser = ArgumentParser(
        prog=PROG, formatter_class=argparse.ArgumentDefaultsHelpFormatter,
        description='Simulate a tracked robot on a terrain, write a calibration bag, run '
                    'identify_icr on it, and compare ideal differential-drive odometry with '
                    'the identified ICRs on held-out paths.',
        epilog='examples:\n'
               '  tracked_kinematics_demo\n'
               '  tracked_kinematics_demo --vehicle packbot --mu-y 0.9 --terrain turf '
               '--output turf_demo')
    add_vehicle_arguments(parser)
    parser.add_argument('--output', '-o', default='demo_output', metavar='DIR',
                        help='directory for every output (a rerun replaces the outputs its '
                             'manifest lists, nothing else)')
    parser.add_argument('--seed', type=SEED, default=0,
                        help='seed of the calibration drive; held-out path k uses seed + k')
    parser.add_argument('--duration', type=bounded(1.0, 3600.0, 's'), default=180.0,
                        metavar='SECONDS', help='length of the calibration drive, 1-3600')
    parser.add_argument('--paths', type=bounded(1, 10, integer=True), default=4,
                        help='number of held-out paths, 1-10')
    parser.add_argument('--path-duration', type=bounded(1.0, 3600.0, 's'), default=60.0,
                        metavar='SECONDS', help='length of each held-out path, 1-3600')
    parser.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap',
                        help='rosbag2 storage of the bags')
    add_force_argument(parser)
    return parser


def _step(number, text, seconds, out):
    print(f'{number}. {text:<78}{seconds:6.1f} s', file=out)


def _indent(text, out, prefix='   | '):
    for line in text.rstrip('\n').splitlines():
        print(prefix + line, file=out)


def run(args, out) -> int:
    """Run the four steps; return the exit status."""
    start = time.perf_counter()
    directory = Path(args.output)
    overrides = overrides_from_args(args)
    spec = load_vehicle(args.vehicle, overrides)
    terrain = str(spec.terrain)
    if not terrain or Path(terrain).name != terrain or terrain.startswith('.'):
        raise DemoError(f'the terrain name {terrain!r} must be a plain file name (it names '
                        'the terrain YAML)')
    outputs = DemoDirectory(directory, force=bool(getattr(args, 'force', False)))
    try:
        outputs.prepare(planned_outputs(spec.name, terrain,
                                        [heldout_name(k) for k in range(args.paths)]))
        status = _steps(args, out, spec, terrain, overrides, outputs, start)
    except BaseException:
        outputs.fail()
        raise
    if status != 0:
        outputs.fail()
    else:
        outputs.done()
    return status


def _steps(args, out, spec, terrain, overrides, outputs: DemoDirectory, start) -> int:
    print(f'{PROG}: {spec.name} on {terrain} ({spec.path}), seed {args.seed}; '
          f'outputs in {outputs.directory}/', file=out)
    table = TwistTable.of(spec.robot.vehicle)
    sim = _simulate_step(args, out, spec, terrain, overrides, outputs, table)
    status = _identify_step(out, spec, terrain, outputs, sim)
    if status != 0:
        return status
    yaml_path = outputs.directory / f'{terrain}.yaml'
    results = _heldout_step(args, out, spec, terrain, overrides, outputs, table, yaml_path)
    _outputs_step(out, outputs, yaml_path, sim, results, start)
    return 0


def _simulate_step(args, out, spec, terrain, overrides, outputs, table):
    """Step 1: simulate and record the calibration drive; return the simulated bag."""
    t = time.perf_counter()
    calibration = f'calibration/{spec.name}_{terrain}'
    outputs.record(Entry('bag', calibration, bag_files(calibration, args.storage)))
    outputs.record(Entry('file', f'{calibration}.truth.yaml'))
    sim = simulate_bag(outputs.directory / calibration, args.vehicle, overrides=overrides,
                       duration=args.duration, seed=args.seed, storage=args.storage,
                       table=table, force=outputs.force, parents=False, imu=GYRO)
    outputs.written()
    truth = sim.truth_icr
    _step(1, f'simulated a calibration drive: mixed manoeuvres, {sim.run.duration:.0f} s, '
          f'{sim.run.distance:.1f} m', time.perf_counter() - t, out)
    print(f'   bag         {sim.bag} ({args.storage}, '
          f'{sum(sim.messages.values()):,} messages)', file=out)
    print(f'   true model  {sim.truth}', file=out)
    print(f"               the simulator's averaged ICR map: chi {fixed(truth.chi)}, "
          f'e {fixed(truth.eccentricity)}', file=out)
    return sim


def _identify_step(out, spec, terrain, outputs, sim) -> int:
    """Step 2: fit the calibration bag as identify_icr does; return its exit status."""
    t = time.perf_counter()
    directory = outputs.directory
    for name in (f'{terrain}.yaml', 'identify_report.json', 'identify.png'):
        outputs.record(Entry('file', name))
    status, command, printed = identify(sim.bag, directory, terrain,
                                        spec.robot.vehicle.track_width,
                                        spec.robot.encoders.sprocket_radius, outputs.force)
    _step(2, 'identified the ICRs with identify_icr (what the console script runs)',
          time.perf_counter() - t, out)
    _print_command(command, out)
    print('   its output; its hold-out table compares the models on 30 s blocks of the '
          'calibration bag:', file=out)
    _indent(printed, out)
    if status != 0:   # identify_icr said why on stderr (a signal ends the demo instead)
        print(f'{PROG}: identify_icr failed with exit status {status} (reason above); '
              'try a longer --duration', file=sys.stderr)
        return status
    outputs.written()
    yaml_path = directory / f'{terrain}.yaml'
    identified = icr_from_values(read_params_file(yaml_path))
    print(f'   fitted YAML {yaml_path} (terrain parameters; fit statistics follow in the file):',
          file=out)
    text = yaml_path.read_text(encoding='utf-8')
    _indent(text.split('    identification:')[0], out)
    truth = sim.truth_icr
    print(f'   identified chi {fixed(identified.chi)}, e {fixed(identified.eccentricity)}; '
          f"simulator's averaged map chi {fixed(truth.chi)}, e {fixed(truth.eccentricity)}",
          file=out)
    return 0


def _print_command(command, out, prefix='   $ ') -> None:
    lines = textwrap.wrap(shlex.join(command), 88, break_long_words=False,
                          break_on_hyphens=False)
    print(prefix + (' \\\n' + ' ' * (len(prefix) + 2)).join(lines), file=out)


def _heldout_step(args, out, spec, terrain, overrides, outputs, table, yaml_path):
    """Step 3: dead-reckon the held-out paths, and score the published covariance on them."""
    t = time.perf_counter()
    directory = outputs.directory
    values = read_params_file(yaml_path)
    identified, gyro = icr_from_values(values), gyro_config_from_values(values)
    results = []
    for k in range(args.paths):
        name = f'heldout/{heldout_name(k)}'
        outputs.record(Entry('bag', name, bag_files(name, args.storage)))
        outputs.record(Entry('file', f'{name}.truth.yaml'))
        results.append(heldout_path(k, args, overrides, table, identified,
                                    directory / 'heldout', gyro))
        outputs.written()
    outputs.record(Entry('file', 'heldout.csv'))
    outputs.record(Entry('file', 'heldout.png'))
    with Outputs(force=outputs.force) as files:
        files.add('heldout.csv', directory / 'heldout.csv')
        files.add('heldout.png', directory / 'heldout.png')
        files.write_text('heldout.csv', csv_text(results))
        from tracked_kinematics.offline.plots import plot_heldout_paths
        with files.path('heldout.png') as tmp:
            plot_heldout_paths(tmp, results, f'{spec.name} on {terrain}: held-out paths, dead '
                               'reckoning from the encoders and gyro-aided')
    outputs.written()
    _step(3, f'dead-reckoned {len(results)} held-out paths (new seeds, not used by the fit)',
          time.perf_counter() - t, out)
    print("   final errors against the true pose; ideal = diff_drive_controller's odometry, "
          f'identified = {yaml_path.name}', file=out)
    print_table(results, out)
    outputs.record(Entry('file', 'consistency.png'))
    _consistency(directory, yaml_path, results, spec, outputs.force, out)
    outputs.written()
    return results


def _outputs_step(out, outputs, yaml_path, sim, results, start) -> None:
    """Step 4: say where every output is, and what to run next (in a venv, in a workspace)."""
    directory = outputs.directory
    print(f'4. outputs (total {time.perf_counter() - start:.1f} s):', file=out)
    listing = (
            (yaml_path, 'identified terrain parameters (--params-file)'),
            (directory / 'identify_report.json', 'identify_icr report: fit, hold-out stats'),
            (directory / 'identify.png', 'identify_icr plot: paths and residuals'),
            (directory / 'heldout.csv', 'held-out errors, one row per path'),
            (directory / 'heldout.png', 'held-out paths: truth, ideal, identified, '
                                        'gyro-aided'),
            (directory / 'consistency.png', 'held-out errors against the published '
                                            'covariance (NEES)'),
            (sim.bag, 'calibration bag (+ .truth.yaml: the true model)'),
            (directory / 'heldout', 'held-out bags'),
            (outputs.manifest, 'what the demo wrote here (a rerun replaces exactly these)'))
    width = max(len(str(path)) for path, _ in listing)
    for path, what in listing:
        print(f'   {str(path):<{width}}  {what}', file=out)
    print('   next (the console scripts are in .venv/bin/ after make demo; in a ROS 2 '
          'workspace: ros2 run tracked_kinematics NAME):', file=out)
    print('   score the fit on the held-out bags (errors, verdicts on the covariance, the row '
          'to run):', file=out)
    bags = [str(directory / 'heldout' / r.name) for r in results]
    _print_command(['evaluate_model', *bags, '--ground-truth-topic', GT_TOPIC, '--params',
                    str(yaml_path), '--fuse-imu', IMU_TOPIC], out, prefix='   ')
    print('   run it on the robot, its gyro on /imu/data:', file=out)
    print('   odometry_node --ros-args --params-file '
          f'{yaml_path.resolve()} -p imu_topic:={IMU_TOPIC}', file=out)


def _consistency(directory, yaml_path, results, spec, force, out) -> None:
    """Score the held-out bags as evaluate_model --fuse-imu does: the covariance's coverage."""
    from tracked_kinematics.core import evaluate as ev
    from tracked_kinematics.core.errors import ExcitationError
    from tracked_kinematics.offline.model_evaluation import (
        check_gyro_rate, evaluate_models, pose_references, TerrainModel)
    from tracked_kinematics.offline.model_evaluation_plot import plot_consistency
    bags = [directory / 'heldout' / r.name for r in results]
    found = []
    for bag, result in zip(bags, results):   # the recordings the paths were read into
        check_gyro_rate(bag, result.recording, IMU_TOPIC)
        found.append((result.recording, None))
    model = TerrainModel(yaml_path)
    settings = ev.Settings((5.0, 10.0), track_width=spec.robot.vehicle.track_width,
                           min_speed=0.1)
    try:
        report = evaluate_models(pose_references(bags, found, 0.0), [model], settings,
                                 sprocket_radius=spec.robot.encoders.sprocket_radius,
                                 fuse_imu=True)
    except ExcitationError as err:
        report = None
        print(f'   the published covariance: not scored ({err})', file=out)
    if report is None:
        normalised = {}
    else:
        normalised = _print_consistency(report, model, yaml_path, out)
    with Outputs(force=force) as files:
        files.add('consistency.png', directory / 'consistency.png')
        with files.path('consistency.png') as tmp:
            plot_consistency(tmp, normalised, settings.windows)


def _print_consistency(report, model, yaml_path, out) -> dict:
    """Print the coverage of the published covariance and its verdict; return the errors."""
    print(f"   the published covariance ({yaml_path.name}'s noise model, fitted by identify_icr) "
          'on the held-out windows, as evaluate_model --fuse-imu reports it:', file=out)
    for name in (model.name, f'{model.name}+imu'):
        windows = report.content['models'][name]['odometry']['windows']
        cells = []
        for key in ('5', '10'):
            c = windows[key]['consistency']
            if not c['windows']:
                cells.append(f'{key} s: no windows (paths too short)')
                continue
            cells.append(f'{key} s: {100 * c["inside_50"]:.0f} % / {100 * c["inside_95"]:.0f} %, '
                         f'NEES {c["mean_nees"]:.1f}: {c["verdict"] or "too few windows"}')
        print(f'   {name:<18}' + '; '.join(cells), file=out)
    print('   (inside the 50 % / 95 % ellipses and mean NEES: 50 % / 95 % and 2 if consistent; '
          'the verdict\'s rule: docs/tools/evaluate_model.md, "The verdict")', file=out)
    return report.normalised


def main(argv=None) -> int:
    """Run the demo; return the exit status (see the module docstring)."""
    return run_main(PROG, run, build_parser().parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
