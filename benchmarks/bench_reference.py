"""
Benchmark: identify_icr without ground truth (issue 21): the gyro, GNSS. Prints figures.

1. Real data, one row per Warthog bag of ../shared/realdata: fit on the other two bags from
   the gyro alone (``/imu/data``), from the lidar ICP (icr_scales, delay estimated), as the
   plain gyro fit (symmetric scales, nominal distance scale), the ideal drive, and the gyro
   and the ICP together (``--imu-topic`` with ``--ground-truth-topic``); scored on
   the held-out bag against its ICP after 5-s windows: mean heading (deg) and position (m)
   error, and the gyro delay found. [heading within 1.15 x the ICP fit's; position no worse
   than the plain gyro fit]
2. Simulation: the Auriga-alpha of the demo, four calibration runs of 240 s with a biased,
   late gyro (0.01 rad/s, 0.08 s) and a 2-m GNSS at 5 Hz, fitted from the gyro alone, the
   gyro and the GNSS (position windows of 30, 60 and 120 s), the true pose (identify_icr's
   pose fit) and ideal drive; scored on
   four held-out 60-s runs against the true pose after 5-s windows. [gyro + GNSS position
   within 1.2 x the pose fit's]. Repeated on the same vehicle with its centre of mass at
   the geometric centre and no height (symmetric, quasi-static: nothing for the GNSS to
   miss but the distance scale).

Run: ``python benchmarks/bench_reference.py [REALDATA_FOLDER]`` (default
``<repository>/../shared/realdata``, or ``$TRACKED_KINEMATICS_REALDATA``).
"""

import math
import os
from pathlib import Path
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent

from tracked_kinematics.core import evaluate as ev  # noqa: E402,I100
from tracked_kinematics.core import identify as ident  # noqa: E402
from tracked_kinematics.core.kinematics import IcrParams  # noqa: E402
from tracked_kinematics.core.sim.sensors import GnssModel, GyroModel  # noqa: E402
from tracked_kinematics.core.sim.simulation import TwistTable  # noqa: E402
from tracked_kinematics.offline.bag_simulation import simulate_bag  # noqa: E402
from tracked_kinematics.offline.bags import (  # noqa: E402
    EncoderSource, GroundTruthSource, read_recording, read_recordings)
from tracked_kinematics.offline.vehicle_file import load_vehicle  # noqa: E402

WINDOWS = (30.0, 60.0, 120.0)
"""GNSS position windows compared, s."""
WARTHOG = ('warthog_grass_2024-07-18_16h59', 'warthog_grass_2024-07-29_14h04',
           'warthog_grass_2024-08-08_16h11')


def folder() -> Path:
    """Return the folder of the real bags."""
    if len(sys.argv) > 1:
        return Path(sys.argv[1])
    named = os.environ.get('TRACKED_KINEMATICS_REALDATA')
    return Path(named) if named else ROOT.parent / 'shared' / 'realdata'


def score(icr, recordings, delay='auto', width=None):
    """Mean 5-s window position (m) and heading (deg) errors of a model."""
    data = []
    for rec in recordings:
        d = ident.estimate_delay([rec]).delay if delay == 'auto' else delay
        data.append(ev.Data(ident.correct_ground_truth([rec], d)[0]))
    report = ev.evaluate(data, [ev.Candidate('m', icr)],
                         ev.Settings(windows=(5.0,), track_width=width or icr.track_width))
    win = report.models['m']['odometry']['windows']['5']
    return win['mean_position_error_m'], math.degrees(win['mean_heading_error_rad'])


def real(base: Path) -> None:
    """Leave-one-out on the Warthog bags."""
    encoders = EncoderSource(sprocket_radius=0.3)
    paths = [base / n for n in WARTHOG]
    gyro = read_recordings(paths, encoders, imu_topic='/imu/data')
    both = read_recordings(paths, encoders, imu_topic='/imu/data',
                           ground_truth=GroundTruthSource('/icp/pose'))
    icp = read_recordings(paths, encoders, ground_truth=GroundTruthSource('/icp/pose'))
    print('bench_reference: Warthog grass, fit on the two other bags, scored on each against '
          'its ICP after 5-s windows: heading deg / position m')
    print(f'    {"held-out bag":<32}{"gyro fit":>16}{"ICP fit":>16}{"plain gyro":>16}'
          f'{"ideal":>16}{"gyro + ICP":>16}{"imu_delay s":>13}{"gyro/ICP hdg":>14}')
    for held, name in enumerate(WARTHOG):
        train = [k for k in range(len(WARTHOG)) if k != held]
        started = time.perf_counter()
        fit = ident.fit_recordings([gyro[k] for k in train], 1.08)
        wall = time.perf_counter() - started
        plain = ident.fit_recordings([gyro[k] for k in train], 1.08, hold=('scale_ratio',))
        posed = ident.identify([icp[k] for k in train], 'icr_scales', 1.08, holdout=0,
                               ground_truth_delay='auto').icr
        combined = ident.fit_recordings([both[k] for k in train], 1.08).icr
        models = (fit.icr, posed, plain.icr, IcrParams.ideal(1.08), combined)
        rows = [score(m, [icp[held]]) for m in models]
        cells = ''.join(f'{h:>8.2f} /{p:>6.3f}' for p, h in rows)
        print(f'    {name:<32}{cells}{fit.imu_delay.delay:>13.3f}'
              f'{rows[0][1] / rows[1][1]:>14.2f}   ({wall:.2f} s)')


def husky(base: Path) -> None:
    """Show the one line for the Husky log, whose /imu/data is empty."""
    try:
        read_recording(base / 'husky_wetgrass_part1', EncoderSource(sprocket_radius=0.15875),
                       imu_topic='/imu/data')
    except ident.SensorDataError as err:
        print(f'bench_reference: husky_wetgrass_part1: {err}')


def _runs(directory, table, overrides, seeds, duration):
    out = []
    for seed in seeds:
        bag = simulate_bag(Path(directory) / f'run{seed}', overrides=overrides,
                           duration=duration, seed=seed, table=table,
                           imu=GyroModel(rate=100.0, bias=0.01, noise_std=0.005,
                                         latency=0.08),
                           gnss=GnssModel(rate=5.0, noise_std=2.0, dropout=0.02))
        out.append(bag.bag)
    return out


def simulated(label, overrides) -> None:
    """Gyro, gyro + 2-m GNSS and the true pose on simulated runs; scored on held-out ones."""
    spec = load_vehicle('auriga_alpha', overrides)
    table = TwistTable(spec.robot.vehicle)
    encoders = EncoderSource(sprocket_radius=spec.robot.encoders.sprocket_radius)
    width = spec.robot.vehicle.track_width
    with tempfile.TemporaryDirectory() as tmp:
        train = _runs(tmp, table, overrides, (101, 102, 103, 104), 240.0)
        test = _runs(tmp, table, overrides, (201, 202, 203, 204), 60.0)
        refs = read_recordings(train, encoders, imu_topic='/imu/data', gnss_topic='/gnss/fix')
        gyro_only = [ident.Recording(r.enc_t, r.left, r.right, gyro_t=r.gyro_t,
                                     gyro_rate=r.gyro_rate, name=r.name) for r in refs]
        poses = read_recordings(train, encoders,
                                ground_truth=GroundTruthSource('/ground_truth/pose'))
        truth = read_recordings(test, encoders,
                                ground_truth=GroundTruthSource('/ground_truth/pose'))
        fits = {'gyro': ident.fit_recordings(gyro_only, width).icr}
        for window in WINDOWS:
            fit = ident.fit_recordings(refs, width, position_window=window)
            fits[f'gyro+GNSS {window:g} s'] = fit.icr
        fits['pose'] = ident.identify(poses, 'icr_scales', width, holdout=0,
                                      ground_truth_delay='auto').icr
        fits['ideal'] = IcrParams.ideal(width)
        rows = {name: score(icr, truth, delay=0.0) for name, icr in fits.items()}
    print(f'bench_reference: simulated {label}: 4 x 240 s to fit, 4 x 60 s held out, 5-s '
          'windows against the true pose')
    pose_position = rows['pose'][0]
    for name, (position, heading) in rows.items():
        icr = fits[name]
        s = 0.5 * (icr.scale_left + icr.scale_right)
        print(f'    {name:<18} position {position:.4f} m ({position / pose_position:5.2f} x '
              f'pose fit), heading {heading:.3f} deg; chi {icr.chi:.3f}, distance scale '
              f'{s:.4f}, icr.x {icr.x:+.3f} m')


def main():
    """Run the real-data rows (when the data are there), then the simulations."""
    base = folder()
    if (base / 'README.md').is_file():
        real(base)
        husky(base)
    else:
        print(f'bench_reference: no real data in {base}; give the folder as the argument')
    simulated('Auriga-alpha (demo vehicle)', None)
    simulated('Auriga-alpha, centre of mass at the centre, no height',
              {'centre_of_mass.x': 0.0, 'centre_of_mass.y': 0.0, 'centre_of_mass.z': 0.0})
    return 0


if __name__ == '__main__':
    sys.exit(main())
