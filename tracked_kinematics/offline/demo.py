"""
Demo on built-in data: ideal differential-drive odometry vs ICR odometry.

A vehicle whose tread ICRs move with lateral acceleration and curvature (the EKF paper's
model, standing in for real track slip) drives a built-in path of straights, turns and a
spin. Its encoder readings are integrated twice: as diff_drive_controller would (ideal
differential drive) and through the constant ICRs of the shipped Auriga-alpha terrain file.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from tracked_kinematics.core.integration import wrap_angle
from tracked_kinematics.core.models import AdaptiveIcr, ConstantIcr, IdealDiffDrive
from tracked_kinematics.params import icr_from_values, read_params_file
from tracked_kinematics.share import config_file


def builtin_path(rate_hz: float = 100.0):
    """
    Nominal track speeds of the built-in path: (v_left, v_right) segments, m/s, and dt.

    Returns
    -------
    v_left, v_right : ndarray
        Measured track speeds, one per encoder sample.
    dt : float
        Sample period, s.

    """
    legs = [  # (v_left, v_right, seconds)
        (0.5, 0.5, 4.0), (0.2, 0.7, 6.0), (0.5, 0.5, 3.0), (0.7, 0.25, 5.0),
        (-0.4, 0.4, 4.0), (0.6, 0.6, 3.0), (0.3, 0.6, 8.0),
    ]
    dt = 1.0 / rate_hz
    v_left = np.concatenate([np.full(int(round(s * rate_hz)), vl) for vl, _, s in legs])
    v_right = np.concatenate([np.full(int(round(s * rate_hz)), vr) for _, vr, s in legs])
    return v_left, v_right, dt


def main(argv=None) -> int:
    """Run the demo and print the table of odometry errors."""
    parser = argparse.ArgumentParser(
        prog='tracked_kinematics_demo', description=__doc__,
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument('--params', default=None,
                        help='terrain YAML for the ICR odometry (default: shipped Auriga-alpha)')
    args = parser.parse_args(argv)
    path = args.params or config_file('auriga_alpha_hard_floor.yaml')
    try:
        icr = icr_from_values(read_params_file(path))
    except (OSError, ValueError) as err:
        print(f'tracked_kinematics_demo: {err}', file=sys.stderr)
        return 2

    v_left, v_right, dt = builtin_path()
    # Stand-in for reality: ICRs that move outwards and forwards as the vehicle turns harder.
    truth = AdaptiveIcr(icr.track_width)
    p_truth = np.array([0.05, 0.07, 0.09, 0.09, 0.02, 0.03])
    x_t, y_t, th_t = truth.integrate(p_truth, v_left * dt, v_right * dt, dt)

    ideal = IdealDiffDrive(icr.track_width)
    x_i, y_i, th_i = ideal.integrate((), v_left * dt, v_right * dt, dt)
    # Scales are part of the terrain file; the stand-in vehicle has perfect encoders.
    icr_model = ConstantIcr(icr.track_width, with_scales=False)
    p_icr = icr_model.from_icr(icr)
    x_c, y_c, th_c = icr_model.integrate(p_icr, v_left * dt, v_right * dt, dt)

    distance = float(np.sum(np.hypot(np.diff(x_t), np.diff(y_t))))
    print(f'terrain file: {path}')
    print(f'ICR model: chi = {icr.chi:.3f}, e = {icr.eccentricity:.3f}')
    print(f'built-in path: {len(v_left) * dt:.0f} s, {distance:.1f} m driven\n')
    print(f'{"odometry":<28}{"final position error":>22}{"heading error":>16}')
    for label, (x, y, th) in (('ideal differential drive', (x_i, y_i, th_i)),
                              ('constant ICRs (terrain)', (x_c, y_c, th_c))):
        err_pos = float(np.hypot(x[-1] - x_t[-1], y[-1] - y_t[-1]))
        err_th = float(abs(wrap_angle(th[-1] - th_t[-1])))
        print(f'{label:<28}{err_pos:>19.3f} m{np.degrees(err_th):>13.1f} deg')
    return 0


if __name__ == '__main__':
    sys.exit(main())
