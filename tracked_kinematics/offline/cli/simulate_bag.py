"""
Simulate a tracked vehicle and record the run as a bag, with its true ICR model next to it.

The bag holds what a real calibration run would: ``/joint_states`` (sensor_msgs/JointState,
``left_sprocket_joint`` / ``right_sprocket_joint`` positions and velocities), a ground-truth
pose (geometry_msgs/PoseStamped on ``/ground_truth/pose``, or nav_msgs/Odometry on
``/ground_truth/odom``), and the commanded setpoints ``/left_track/setpoint`` and
``/right_track/setpoint`` (std_msgs/Float64, m/s), so the drive train can be identified from
it too; with ``--imu`` a gyro on ``/imu/data`` (sensor_msgs/Imu, ``angular_velocity.z`` with
bias, noise, latency; ``orientation_covariance[0] = -1``) and with ``--gnss`` a receiver on
``/gnss/fix`` (sensor_msgs/NavSatFix with noise, dropouts and fix status), the sensors of a
robot without ground truth (:mod:`tracked_kinematics.core.sim.sensors`). Next to it,
``OUT.truth.yaml`` holds the vehicle's averaged stationary ICR model in the terrain format (a
valid ``--params-file``): the ground truth an identification should find, and the sensor
settings used (``simulation.imu.*``, ``simulation.gnss.*``).

The command line of :func:`tracked_kinematics.offline.bag_simulation.simulate_bag` (the library
that scripts and the demo call).

Exit status: 0 success; 2 bad input (vehicle, option, an output path that may not be
written, a file that cannot be written); 130 / 143 interrupted. The bag is written to a
hidden temporary directory and renamed when closed, the truth file likewise, both at the end
or neither (docs/output-files.md).

Documentation: docs/tools/simulate_bag.md.
"""

from __future__ import annotations

import argparse
import math
import sys

from tracked_kinematics.core.sim.manoeuvres import MANOEUVRES
from tracked_kinematics.core.sim.sensors import GnssModel, GyroModel
from tracked_kinematics.offline.bag_simulation import (
    GNSS_STATUS, GROUND_TRUTH_TOPICS, MAX_DURATION, MAX_SAMPLES, RATES, simulate_bag, TOOL)
from tracked_kinematics.offline.bags import STORAGES
from tracked_kinematics.offline.cli.common import (
    add_force_argument, ArgumentParser, bounded, run_main, SEED)
from tracked_kinematics.offline.vehicle_file import (
    add_vehicle_arguments, fixed, overrides_from_args)

PROG = TOOL


# Command line -----------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    """Argument parser of ``simulate_bag``."""
    parser = ArgumentParser(
        prog=PROG, formatter_class=argparse.ArgumentDefaultsHelpFormatter,
        description='Simulate a tracked vehicle (stationary track-soil dynamics, drive train, '
                    'encoders, ground truth) and write the run as a bag, with the true ICR '
                    'model as OUT.truth.yaml next to it.',
        epilog='examples:\n'
               '  simulate_bag run1 --vehicle auriga_alpha --duration 180 --seed 1\n'
               '  simulate_bag sweep.bag --vehicle packbot --manoeuvres sweep --storage rosbag1\n'
               '  simulate_bag turf --vehicle packbot --mu-y 0.9 --terrain turf '
               '--ground-truth odometry --storage mcap\n'
               '  simulate_bag field --imu --imu-bias 0.01 --imu-latency 0.1 --gnss '
               '--gnss-noise 2')
    parser.add_argument('output', help='bag to create: a rosbag2 directory, or X.bag with '
                                       '--storage rosbag1 (must not exist; its directory must)')
    add_vehicle_arguments(parser.add_argument_group('vehicle and terrain'))
    run = parser.add_argument_group('run')
    run.add_argument('--manoeuvres', choices=MANOEUVRES, default='mixed',
                     help='random: manual-like driving; sweep: Fink & Stump speed x curvature '
                          'grid; spin: spins in place; mixed: all three')
    run.add_argument('--duration', type=bounded(0.1, MAX_DURATION, 's'), default=180.0,
                     help=f'length of the run, s, 0.1-{MAX_DURATION:g} (and at most '
                          f'{MAX_SAMPLES:,} samples at --rate and --gt-rate)')
    run.add_argument('--seed', type=SEED, default=0, help='seed of every random choice')
    sensors = parser.add_argument_group('sensors')
    sensors.add_argument('--rate', type=bounded(*RATES['rate'], 'Hz'), default=100.0,
                         help='encoder (joint_states) and simulation rate, Hz, 1-2000')
    sensors.add_argument('--setpoint-rate', type=bounded(*RATES['setpoint_rate'], 'Hz'),
                         default=50.0, help='rate of the track speed commands, Hz, 1-2000 '
                                            '(at most --rate)')
    sensors.add_argument('--ticks-per-rev', type=bounded(0.0, 1e9), default=argparse.SUPPRESS,
                         help='encoder ticks per sprocket revolution, 0 for none (overrides '
                              'the file)')
    sensors.add_argument('--encoder-noise', type=bounded(0.0, 100.0, 'rad/s'),
                         default=argparse.SUPPRESS,
                         help='white noise on the joint velocities, rad/s, 0-100 (overrides '
                              'the file)')
    sensors.add_argument('--gt-rate', type=bounded(*RATES['gt_rate'], 'Hz'), default=10.0,
                         help='ground-truth rate, Hz, 0.1-1000')
    sensors.add_argument('--gt-noise-xy', type=bounded(0.0, 1.0, 'm'), default=0.002,
                         help='ground-truth position noise (standard deviation), m, 0-1')
    sensors.add_argument('--gt-noise-yaw', type=bounded(0.0, 1.0, 'rad'), default=0.002,
                         help='ground-truth heading noise (standard deviation), rad, 0-1')
    imu = parser.add_argument_group('IMU (--imu: sensor_msgs/Imu on /imu/data, gyro only)')
    imu.add_argument('--imu', action='store_true', help='record a gyro')
    imu.add_argument('--imu-rate', type=bounded(1.0, 2000.0, 'Hz'), default=100.0,
                     help='gyro rate, Hz')
    imu.add_argument('--imu-bias', type=bounded(-1.0, 1.0, 'rad/s'), default=0.005,
                     help='gyro bias, rad/s')
    imu.add_argument('--imu-noise', type=bounded(0.0, 1.0, 'rad/s'), default=0.002,
                     help='white noise of one reading (standard deviation), rad/s')
    imu.add_argument('--imu-bias-walk', type=bounded(0.0, 0.1, 'rad/s/sqrt(s)'), default=0.0,
                     help='random walk of the bias, rad/s/sqrt(s)')
    imu.add_argument('--imu-latency', type=bounded(-1.0, 1.0, 's'), default=0.0,
                     help='the gyro is stamped this late behind the truth (the encoders are '
                          'not), s; identify_icr finds it as imu_delay')
    imu.add_argument('--imu-scale', type=bounded(0.5, 2.0), default=1.0,
                     help='scale error of the gyro: reading over true rate (identify_icr fits '
                     'it as gyro_scale when it has a pose)')
    imu.add_argument('--imu-saturation', type=bounded(0.01, 100.0, 'rad/s'), default=math.inf,
                     help='largest rate the gyro reports, rad/s (inf: none)')
    gnss = parser.add_argument_group('GNSS (--gnss: sensor_msgs/NavSatFix on /gnss/fix)')
    gnss.add_argument('--gnss', action='store_true', help='record a GNSS receiver')
    gnss.add_argument('--gnss-rate', type=bounded(0.1, 100.0, 'Hz'), default=5.0,
                      help='fix rate, Hz')
    gnss.add_argument('--gnss-noise', type=bounded(0.0, 100.0, 'm'), default=2.0,
                      help='position noise per axis (standard deviation), m: 1-3 standalone, '
                           '0.02 RTK')
    gnss.add_argument('--gnss-correlation-time', type=bounded(0.0, 3600.0, 's'), default=0.0,
                      help='time constant of the position error, s (0: white)')
    gnss.add_argument('--gnss-latency', type=bounded(-1.0, 5.0, 's'), default=0.0,
                      help='the fixes are stamped this late, s')
    gnss.add_argument('--gnss-dropout', type=bounded(0.0, 1.0), default=0.0,
                      help='probability that a fix is missing (status -1, NO_FIX)')
    gnss.add_argument('--gnss-antenna', type=bounded(-10.0, 10.0, 'm'), nargs=2,
                      default=(0.0, 0.0), metavar=('X', 'Y'),
                      help='antenna position in base_link, m')
    gnss.add_argument('--gnss-status', choices=tuple(GNSS_STATUS), default='fix',
                      help='status of a good fix: fix (standalone), sbas, gbas (RTK)')
    output = parser.add_argument_group('output')
    output.add_argument('--ground-truth', choices=tuple(GROUND_TRUTH_TOPICS), default='pose',
                        help='ground truth as geometry_msgs/PoseStamped or nav_msgs/Odometry')
    output.add_argument('--gt-topic', default=argparse.SUPPRESS,
                        help='ground-truth topic (default /ground_truth/pose or '
                             '/ground_truth/odom)')
    output.add_argument('--storage', choices=STORAGES, default='sqlite3', help='bag format')
    output.add_argument('--truth', default=argparse.SUPPRESS,
                        help='where to write the true ICR model (default OUT.truth.yaml)')
    add_force_argument(output)
    return parser


def _imu_model(args) -> GyroModel | None:
    if not args.imu:
        return None
    return GyroModel(rate=args.imu_rate, bias=args.imu_bias, noise_std=args.imu_noise,
                     bias_walk=args.imu_bias_walk, latency=args.imu_latency,
                     scale=args.imu_scale, saturation=args.imu_saturation)


def _gnss_model(args) -> GnssModel | None:
    if not args.gnss:
        return None
    return GnssModel(rate=args.gnss_rate, noise_std=args.gnss_noise,
                     correlation_time=args.gnss_correlation_time, latency=args.gnss_latency,
                     dropout=args.gnss_dropout, antenna_x=args.gnss_antenna[0],
                     antenna_y=args.gnss_antenna[1], status=GNSS_STATUS[args.gnss_status])


def _run(args, out) -> int:
    result = simulate_bag(
        args.output, args.vehicle, overrides=overrides_from_args(args),
        manoeuvres=args.manoeuvres, duration=args.duration, seed=args.seed,
        rate=args.rate, setpoint_rate=args.setpoint_rate, gt_rate=args.gt_rate,
        gt_position_noise=args.gt_noise_xy, gt_yaw_noise=args.gt_noise_yaw,
        ground_truth=args.ground_truth, ground_truth_topic=getattr(args, 'gt_topic', None),
        storage=args.storage, truth=getattr(args, 'truth', None), force=args.force,
        parents=False, imu=_imu_model(args), gnss=_gnss_model(args))
    run, icr = result.run, result.truth_icr
    print(f'vehicle      {result.vehicle.name} on {result.vehicle.terrain} '
          f'({result.vehicle.path})', file=out)
    print(f'run          {args.manoeuvres}, {run.duration:.1f} s, {run.distance:.1f} m, '
          f'seed {args.seed}', file=out)
    print(f'bag          {result.bag} ({args.storage})', file=out)
    for topic, count in result.messages.items():
        print(f'  {topic:<26}{count:>8} messages', file=out)
    print(f'true model   {result.truth}', file=out)
    print(f'  icr.y_left {fixed(icr.y_left, 4)}  icr.y_right {fixed(icr.y_right, 4)}  '
          f'icr.x {fixed(icr.x, 4)} m  scale {icr.scale_left:.4f} / {icr.scale_right:.4f}',
          file=out)
    print(f'  chi {fixed(icr.chi)}  e {fixed(icr.eccentricity)}', file=out)
    return 0


def main(argv=None) -> int:
    """Run ``simulate_bag``; return the exit status (see the module docstring)."""
    return run_main(PROG, _run, build_parser().parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
