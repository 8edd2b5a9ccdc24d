"""
Simulate a tracked vehicle and record the run as a bag, with its true ICR model next to it.

:func:`simulate_bag` does it all in one call (the ``simulate_bag`` command line, the demo,
benchmarks and tests call it); :func:`write_run` records any
:class:`~tracked_kinematics.core.sim.simulation.Run`. The bag's topics and the truth file:
docs/tools/simulate_bag.md; both are written at the end or neither (docs/output-files.md).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import contextlib
from dataclasses import dataclass
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.core.geodesy import GeoOrigin
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.sim.manoeuvres import manoeuvre
from tracked_kinematics.core.sim.sensors import (
    enu_to_geodetic, gnss_samples, GnssModel, gyro_samples, GyroModel)
from tracked_kinematics.core.sim.simulation import GroundTruth, Run, simulate, TwistTable
from tracked_kinematics.offline import signals
from tracked_kinematics.offline.bags import BagWriter, STORAGES
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.outputs import Outputs
from tracked_kinematics.offline.vehicle_file import load_vehicle, vehicle_path, VehicleFile
from tracked_kinematics.params import params_text, values_from_icr

TOOL = 'simulate_bag'
"""The tool named in the truth file."""
JOINTS = ('left_sprocket_joint', 'right_sprocket_joint')
START_NS = 1_700_000_000 * 1_000_000_000
"""Stamp of the first sample (fixed, so that the same seed gives the same messages)."""
GROUND_TRUTH_TOPICS = {'pose': '/ground_truth/pose', 'odometry': '/ground_truth/odom'}
IMU_TOPIC = '/imu/data'
GNSS_TOPIC = '/gnss/fix'
GNSS_ORIGIN = GeoOrigin(46.7815, -71.2750, 100.0)
"""Where the simulated GNSS puts the start of the run (a field near Quebec City)."""
GNSS_STATUS = {'fix': 0, 'sbas': 1, 'gbas': 2}
MAX_SAMPLES = 1_000_000
"""Most encoder or ground-truth samples of one run (2.8 h at 100 Hz), checked before any work."""
RATES = {'rate': (1.0, 2000.0), 'setpoint_rate': (1.0, 2000.0), 'gt_rate': (0.1, 1000.0)}
"""Ranges of the rates, Hz."""
MAX_DURATION = 36000.0
"""Longest run, s (10 h; and at most :data:`MAX_SAMPLES`)."""


@dataclass(frozen=True)
class SimulatedBag:
    """
    What :func:`simulate_bag` wrote.

    Attributes
    ----------
    bag : Path
        The rosbag2 directory or ROS 1 ``.bag`` file.
    truth : Path
        The true averaged ICR model, terrain YAML.
    truth_icr : IcrParams
        The same model.
    run : Run
        The simulated run (true poses, speeds, sensor readings).
    messages : dict
        Messages written per topic.
    vehicle : VehicleFile
        The vehicle simulated.

    """

    bag: Path
    truth: Path
    truth_icr: IcrParams
    run: Run
    messages: dict
    vehicle: VehicleFile


def truth_path(bag: str | os.PathLike) -> Path:
    """``OUT.truth.yaml`` next to a bag (``run`` -> ``run.truth.yaml``, ``run.bag`` too)."""
    bag = Path(bag)
    stem = bag.name[:-4] if bag.name.endswith('.bag') else bag.name
    return bag.with_name(f'{stem}.truth.yaml')


def write_run(path: str | os.PathLike, run: Run, storage: str = 'sqlite3',
              setpoint_rate: float | None = None, ground_truth: str = 'pose',
              ground_truth_topic: str | None = None, frame_id: str = 'map',
              joints: Sequence[str] = JOINTS, start_ns: int = START_NS, gyro=None,
              gnss=None, imu_noise: float = 0.0, gnss_noise: float = 0.0) -> dict:
    """
    Record a simulated run as a bag, messages in time order.

    Parameters
    ----------
    path : path-like
        Bag to create (a rosbag2 directory, or a ``.bag`` file for ``storage='rosbag1'``);
        must not exist.
    run : Run
        The run.
    storage : {'sqlite3', 'mcap', 'rosbag1'}
        Bag format.
    setpoint_rate : float, optional
        Rate at which the run's commands were held, Hz: one setpoint message per hold, stamped
        at the encoder sample where it takes effect (default: one per encoder sample).
    ground_truth : {'pose', 'odometry'}
        geometry_msgs/PoseStamped or nav_msgs/Odometry (with the true body twist).
    ground_truth_topic : str, optional
        Default ``/ground_truth/pose`` or ``/ground_truth/odom``.
    frame_id : str
        Fixed frame of the ground truth.
    joints : sequence of str
        Names of the left and right sprocket joints.
    start_ns : int
        Stamp of the run's time 0, ns.
    gyro : tuple of ndarray, optional
        ``(stamps, z_rate)`` of a gyro (s, rad/s), written on :data:`IMU_TOPIC`.
    gnss : tuple of ndarray, optional
        ``(stamps, latitude, longitude, altitude, status)`` of a receiver, written on
        :data:`GNSS_TOPIC`.
    imu_noise, gnss_noise : float
        Standard deviations written as the messages' covariances (rad/s, m).

    Returns
    -------
    dict
        Messages written per topic.

    """
    if ground_truth not in GROUND_TRUTH_TOPICS:
        raise UsageError(f'ground_truth must be one of {", ".join(GROUND_TRUTH_TOPICS)}, '
                         f'got {ground_truth!r}')
    gt_topic = ground_truth_topic or GROUND_TRUTH_TOPICS[ground_truth]
    dt = float(run.t[1] - run.t[0])
    if setpoint_rate is None:
        setpoint_idx = np.arange(len(run.t))
    else:
        # Setpoint j takes effect at the first encoder sample of its hold (see simulate_bag).
        first = np.ceil(np.arange(int(run.t[-1] * setpoint_rate + 1e-9) + 1)
                        / (setpoint_rate * dt) - 1e-9).astype(int)
        setpoint_idx = np.unique(first[first < len(run.t)])
    stamps = [start_ns + np.round(run.t * 1e9).astype(np.int64),
              start_ns + np.round(run.t[setpoint_idx] * 1e9).astype(np.int64),
              start_ns + np.round(run.gt_t * 1e9).astype(np.int64)]
    for extra in (gyro, gnss):
        stamps.append(np.zeros(0, dtype=np.int64) if extra is None else
                      start_ns + np.round(np.asarray(extra[0]) * 1e9).astype(np.int64))
    kinds = np.concatenate([np.full(len(s), k) for k, s in enumerate(stamps)])
    index = np.concatenate([np.arange(len(s)) for s in stamps])
    order = np.lexsort((kinds, np.concatenate(stamps)))
    all_stamps = np.concatenate(stamps)[order]
    # Twist at the ground-truth times, for Odometry: the step each sample falls in.
    gt_step = np.clip(np.floor(run.gt_t / dt + 1e-9).astype(int), 0, len(run.twist) - 1)
    positions = run.joint_position.tolist()
    velocities = run.joint_velocity.tolist()
    commands = run.commands[setpoint_idx].tolist()
    gt = run.gt_pose.tolist()
    gt_twist = run.twist[gt_step].tolist()
    counts = {'/joint_states': len(stamps[0]), '/left_track/setpoint': len(stamps[1]),
              '/right_track/setpoint': len(stamps[1]), gt_topic: len(stamps[2])}
    if gyro is not None:
        counts[IMU_TOPIC] = len(stamps[3])
        gyro_z = np.asarray(gyro[1], dtype=float).tolist()
    if gnss is not None:
        counts[GNSS_TOPIC] = len(stamps[4])
        fixes = np.column_stack([np.nan_to_num(np.asarray(v, dtype=float), nan=0.0)
                                 for v in gnss[1:]]).tolist()
    names = list(joints)
    with BagWriter(path, storage) as bag:
        for stamp, kind, i in zip(all_stamps.tolist(), kinds[order].tolist(),
                                  index[order].tolist()):
            if kind == 0:
                bag.write('/joint_states', stamp,
                          bag.joint_state(stamp, names, positions[i], velocities[i]))
            elif kind == 1:
                bag.write('/left_track/setpoint', stamp, bag.float64(commands[i][0]))
                bag.write('/right_track/setpoint', stamp, bag.float64(commands[i][1]))
            elif kind == 3:
                bag.write(IMU_TOPIC, stamp, bag.imu(stamp, gyro_z[i],
                                                    rate_variance=imu_noise ** 2))
            elif kind == 4:
                lat, lon, alt, status = fixes[i]
                bag.write(GNSS_TOPIC, stamp, bag.nav_sat_fix(
                    stamp, lat, lon, alt, int(status), position_variance=gnss_noise ** 2))
            elif ground_truth == 'pose':
                bag.write(gt_topic, stamp, bag.pose_stamped(stamp, *gt[i], frame_id=frame_id))
            else:
                v_x, v_y, w = gt_twist[i]
                bag.write(gt_topic, stamp, bag.odometry(stamp, *gt[i], v_x=v_x, v_y=v_y, w=w,
                                                        frame_id=frame_id))
    return counts


def simulate_bag(output: str | os.PathLike, vehicle: str | os.PathLike = 'auriga_alpha', *,
                 overrides: Mapping[str, Any] | None = None, manoeuvres: str = 'mixed',
                 duration: float = 180.0, seed: int = 0, rate: float = 100.0,
                 setpoint_rate: float = 50.0, gt_rate: float = 10.0,
                 gt_position_noise: float = 0.002, gt_yaw_noise: float = 0.002,
                 ground_truth: str = 'pose', ground_truth_topic: str | None = None,
                 storage: str = 'sqlite3', truth: str | os.PathLike | None = None,
                 table: TwistTable | None = None, force: bool = False,
                 parents: bool = True, imu: GyroModel | None = None,
                 gnss: GnssModel | None = None,
                 gnss_origin: GeoOrigin = GNSS_ORIGIN) -> SimulatedBag:
    """
    Simulate a run of a vehicle, write it as a bag and its true ICR model as YAML.

    Both outputs are checked before the simulation and written through
    :class:`~tracked_kinematics.offline.outputs.Outputs`: the bag to a hidden temporary
    directory renamed when it is closed, the YAML atomically, both at the end or neither.

    Parameters
    ----------
    output : path-like
        Bag to create (must not exist): a rosbag2 directory, or ``X.bag`` for rosbag1.
    vehicle : str or path-like
        Vehicle file, or a shipped vehicle's name (``auriga_alpha``, ``packbot``).
    overrides : mapping, optional
        Vehicle parameters replacing the file's (``{'friction.mu_y': 0.9}``).
    manoeuvres : {'random', 'sweep', 'spin', 'mixed'}
        Manoeuvre set (:mod:`tracked_kinematics.core.sim.manoeuvres`).
    duration : float
        Length of the run, s (at most :data:`MAX_DURATION`).
    seed : int
        Seed of every random choice (manoeuvres, sensor noise), >= 0.
    rate : float
        Encoder (JointState) rate and simulation rate, Hz (:data:`RATES`).
    setpoint_rate : float
        Command rate, Hz: commands are generated and recorded at this rate and held.
    gt_rate : float
        Ground-truth rate, Hz.
    gt_position_noise, gt_yaw_noise : float
        Standard deviations of the ground-truth noise, m and rad.
    ground_truth : {'pose', 'odometry'}
        Message type of the ground truth.
    ground_truth_topic : str, optional
        Its topic (default ``/ground_truth/pose`` or ``/ground_truth/odom``).
    storage : {'sqlite3', 'mcap', 'rosbag1'}
        Bag format.
    truth : path-like, optional
        Where to write the true model (default :func:`truth_path` of the bag).
    table : TwistTable, optional
        Precomputed dynamics of this vehicle, to reuse across calls.
    force : bool
        Replace an existing truth file (never an existing bag).
    parents : bool
        Create missing parent directories of the bag (the command line does not).
    imu : GyroModel, optional
        Record a gyro on :data:`IMU_TOPIC` (its bias, noise, latency, rate in the truth file).
    gnss : GnssModel, optional
        Record a GNSS receiver on :data:`GNSS_TOPIC`, the run's start at ``gnss_origin``
        (x east, y north).
    gnss_origin : GeoOrigin
        Latitude, longitude and altitude of the run's start.

    Returns
    -------
    SimulatedBag

    Raises
    ------
    FileNotFoundError, InvalidParameters, UsageError, OutputError
        For a missing vehicle, invalid parameters or settings, or an output that may not be
        written (an existing bag, an existing truth file without ``force``, a link).

    """
    output = Path(output)
    if storage not in STORAGES:
        raise UsageError(f'storage must be one of {", ".join(STORAGES)}, got {storage!r}')
    if storage == 'rosbag1' and output.suffix != '.bag':
        raise UsageError(f'a ROS 1 bag needs a .bag file name, got {os.fspath(output)!r}')
    check_settings(duration, rate, setpoint_rate, gt_rate)
    truth = Path(truth) if truth is not None else truth_path(output)
    created = []
    try:
        if parents:
            missing = [p for p in (output.parent, *output.parent.parents) if not p.exists()]
            for parent in reversed(missing):
                with signals.held():   # made and recorded, or neither
                    parent.mkdir()
                    created.append(parent)
        with Outputs(force=force) as out:
            out.add('OUT', output, directory=True)
            out.add('--truth', truth)
            out.refuse_inputs('--vehicle', [vehicle_path(vehicle)])
            spec = load_vehicle(vehicle, overrides)
            run = _simulated_run(spec, manoeuvres, duration, seed, rate, setpoint_rate,
                                 GroundTruth(gt_rate, gt_position_noise, gt_yaw_noise), table)
            simulation = {
                'bag': output.name, 'manoeuvres': manoeuvres, 'duration': float(duration),
                'seed': int(seed), 'rate': float(rate), 'setpoint_rate': float(setpoint_rate),
                'gt_rate': float(gt_rate), 'gt_position_noise': float(gt_position_noise),
                'gt_yaw_noise': float(gt_yaw_noise)}
            gyro, fixes = _sensor_samples(run, seed, imu, gnss, gnss_origin, simulation)
            with out.path('OUT') as tmp:
                counts = write_run(tmp, run, storage, setpoint_rate, ground_truth,
                                   ground_truth_topic, gyro=gyro, gnss=fixes,
                                   imu_noise=imu.noise_std if imu else 0.0,
                                   gnss_noise=gnss.noise_std if gnss else 0.0)
            icr = spec.robot.true_icr()
            out.write_text('--truth', params_text(truth_values(spec, icr, run, simulation),
                                                  comment=_truth_comment(spec)))
    except BaseException:
        with signals.held():
            for parent in reversed(created):
                with contextlib.suppress(OSError):
                    parent.rmdir()
        raise
    return SimulatedBag(output, truth, icr, run, counts, spec)


def _simulated_run(spec: VehicleFile, manoeuvres, duration, seed, rate, setpoint_rate,
                   ground_truth: GroundTruth, table) -> Run:
    """Drive the vehicle through its manoeuvres and record it (:func:`simulate`)."""
    robot, veh = spec.robot, spec.robot.vehicle
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate
    # Commands at the setpoint rate, held between setpoints, sampled at the encoder rate.
    cmd = manoeuvre(manoeuvres, duration, 1.0 / setpoint_rate, veh.track_width,
                    veh.max_track_speed, rng)
    n = max(2, int(round(duration * rate)) + 1)
    held = np.minimum(np.floor(np.arange(n) * (dt * setpoint_rate) + 1e-9).astype(int),
                      len(cmd) - 1)
    if table is None:
        try:
            table = TwistTable.of(veh)
        except RuntimeError as err:   # the stationary solver fails for this vehicle
            raise InvalidParameters(f'{spec.path}: {err}') from None
    return simulate(robot, cmd[held], dt, table, ground_truth, rng)


def _sensor_samples(run: Run, seed, imu, gnss, gnss_origin, simulation: dict):
    """
    Return the gyro's and the GNSS receiver's samples of a run (None when not asked for).

    Their settings are added to ``simulation`` (the truth file's ``simulation.*``).
    """
    gyro = fixes = None
    if imu is not None:
        # Sensors draw from their own streams: adding one leaves the run unchanged.
        gyro = gyro_samples(run.t, run.twist[:, 2], imu, np.random.default_rng([seed, 1]))
        simulation.update({f'imu.{k}': float(getattr(imu, k)) for k in (
            'rate', 'bias', 'noise_std', 'bias_walk', 'latency', 'scale', 'saturation')
            if math.isfinite(getattr(imu, k))})
        simulation.update({'imu.topic': IMU_TOPIC, 'imu.expected_imu_delay':
                           float(imu.latency)})
    if gnss is not None:
        stamps, east, north, status = gnss_samples(
            run.t, *run.pose.T, gnss, np.random.default_rng([seed, 2]))
        lat, lon, alt = enu_to_geodetic(east, north, np.zeros(east.size), gnss_origin)
        fixes = (stamps, lat, lon, alt, status)
        simulation.update({f'gnss.{k}': float(getattr(gnss, k)) for k in (
            'rate', 'noise_std', 'correlation_time', 'latency', 'dropout', 'antenna_x',
            'antenna_y')})
        simulation.update({'gnss.status': int(gnss.status), 'gnss.topic': GNSS_TOPIC,
                           'gnss.origin_latitude': gnss_origin.latitude,
                           'gnss.origin_longitude': gnss_origin.longitude,
                           'gnss.origin_altitude': gnss_origin.altitude})
    return gyro, fixes


def _truth_comment(spec: VehicleFile) -> str:
    return (f'True kinematic model of the simulated {spec.name} on {spec.terrain}: tread '
            'ICRs\naveraged over the 21 x 21 stationary ICR map (Martinez et al. 2005, '
            'sec. 5.2) and\nthe simulated encoder scales. run_fit: the constant ICRs that '
            "best explain this\nrun's true motion. Written by "
            f'{TOOL}; valid as --params-file.')


def check_settings(duration: float, rate: float, setpoint_rate: float = 1.0,
                   gt_rate: float = 1.0) -> None:
    """
    Check the length and rates of a run before any work: ranges and sample counts.

    Raises
    ------
    UsageError
        Naming the option (``--duration``, ``--rate``, ``--setpoint-rate``, ``--gt-rate``).

    """
    for name, value in (('duration', duration), ('rate', rate),
                        ('setpoint_rate', setpoint_rate), ('gt_rate', gt_rate)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                not math.isfinite(value):
            raise UsageError(f'--{name.replace("_", "-")} must be a finite number, got '
                             f'{value!r}')
    if not 0.0 < duration <= MAX_DURATION:
        raise UsageError(f'--duration must be in (0, {MAX_DURATION:g}] s, got {duration!r}')
    for name, (low, high) in RATES.items():
        value = {'rate': rate, 'setpoint_rate': setpoint_rate, 'gt_rate': gt_rate}[name]
        if not low <= value <= high:
            raise UsageError(f'--{name.replace("_", "-")} must be in [{low:g}, {high:g}] Hz, '
                             f'got {value!r}')
    if setpoint_rate > rate:
        raise UsageError(f'--setpoint-rate ({setpoint_rate:g} Hz) must not exceed the encoder '
                         f'rate ({rate:g} Hz)')
    for flag, value in (('--rate', rate), ('--gt-rate', gt_rate)):
        samples = duration * value
        if samples > MAX_SAMPLES:
            raise UsageError(f'--duration {duration:g} s at {flag} {value:g} Hz is '
                             f'{samples:,.0f} samples (at most {MAX_SAMPLES:,}); shorten '
                             f'--duration or lower {flag}')


def truth_values(spec: VehicleFile, icr: IcrParams, run: Run,
                 simulation: Mapping[str, Any]) -> dict:
    """Terrain parameters of the true model plus provenance, dotted names."""
    values = values_from_icr(icr, spec.robot.encoders.sprocket_radius)
    values.update({'chi': icr.chi, 'eccentricity': icr.eccentricity, 'vehicle': spec.name,
                   'terrain': spec.terrain,
                   'source': 'simulate_bag: averaged stationary ICR map (Martinez sec. 5.2)'})
    best = run.best_constant_icr(icr.track_width)
    if best is not None:
        values.update({'run_fit.y_left': best.y_left, 'run_fit.y_right': best.y_right,
                       'run_fit.x': best.x})
    values.update({f'simulation.{key}': value for key, value in simulation.items()})
    return {k: (float(v) if isinstance(v, (float, np.floating)) else v)
            for k, v in values.items()}
