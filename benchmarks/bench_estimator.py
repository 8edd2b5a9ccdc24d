"""
Benchmark: the EKF paper's simulations (sec. 4) and the cost of one EKF update.

Prints, over five noise seeds:
- sec. 4.1, abrupt ICR change (1.23 -> 2.23 m, x 0 -> 0.5 m at 2 s; again at 12 s): time until
  the estimated ICRs stay within 0.15 m, steady error, and the 2-s prediction error with the
  estimate vs no-slip (the paper's anchor: about 75 % less);
- sec. 4.2, 1 Hz poses with 10 Hz encoders: ICR error of this filter (pose changes) and of
  the velocity-based method, and their 2-s prediction errors;
- sec. 5.3, heading-only updates (RTK outage): prediction error reduction;
- the time of one update (1-s window of 100 Hz encoder steps) and of a 2-s prediction.
"""

import statistics
import time

import numpy as np

from tracked_kinematics.core.estimate import scenarios as sc
from tracked_kinematics.core.estimate.ekf import SlipEstimator
from tracked_kinematics.core.models import AdaptiveIcr
from tracked_kinematics.core.prediction import hold_speeds, predict_path

SEEDS = range(5)


def _reduction(errors, kind):
    slip, noslip = errors[f'slip_{kind}'].mean(), errors[f'noslip_{kind}'].mean()
    return slip, noslip, 100.0 * (1.0 - slip / noslip)


def abrupt():
    """Sec. 4.1 figures."""
    rows = []
    for seed in SEEDS:
        scenario = sc.abrupt_change(seed=seed)
        model = AdaptiveIcr(scenario.track_width)
        run = sc.run_filter(scenario, SlipEstimator(model))
        errors = sc.prediction_errors(scenario, model, run, start=3.0)
        steady = (run.t > 8.0) & (run.t < 12.0)
        rows.append((sc.settling_time(run, scenario, 2.0, 0.15, until=12.0),
                     sc.settling_time(run, scenario, 12.0, 0.15),
                     sc.icr_error(run, scenario, start=8.0) if steady.any() else np.nan,
                     *_reduction(errors, 'position'), *_reduction(errors, 'heading')))
        heading = sc.run_filter(scenario, SlipEstimator(model), heading_only=True)
        h_errors = sc.prediction_errors(scenario, model, heading, start=3.0)
        rows[-1] += (*_reduction(h_errors, 'position'), *_reduction(h_errors, 'heading'))
    r = np.array(rows)
    print('sec. 4.1 abrupt ICR change, adaptive model, 10 Hz poses (2 cm, 0.01 rad), 100 Hz '
          'encoders')
    print(f'  settled within 0.15 m after the 2 s jump: {r[:, 0].min():.1f}-{r[:, 0].max():.1f} s;'
          f' after the 12 s jump: {r[:, 1].min():.1f}-{r[:, 1].max():.1f} s')
    print(f'  mean ICR error 8-20 s (includes the 12 s jump): {r[:, 2].mean():.3f} m')
    print(f'  2-s prediction, position: {r[:, 3].mean():.3f} m vs no-slip {r[:, 4].mean():.3f} m'
          f' ({r[:, 5].mean():.0f} % less)')
    print(f'  2-s prediction, heading:  {r[:, 6].mean():.3f} rad vs no-slip '
          f'{r[:, 7].mean():.3f} rad ({r[:, 8].mean():.0f} % less)')
    print('sec. 5.3 heading-only updates (same runs):')
    print(f'  position {r[:, 9].mean():.3f} m vs {r[:, 10].mean():.3f} m ({r[:, 11].mean():.0f} %'
          f' less); heading {r[:, 12].mean():.3f} rad vs {r[:, 13].mean():.3f} rad '
          f'({r[:, 14].mean():.0f} % less)')


def low_rate():
    """Sec. 4.2 figures."""
    rows = []
    for seed in SEEDS:
        scenario = sc.low_rate(seed=seed)
        model = AdaptiveIcr(scenario.track_width)
        row = []
        for estimator in (SlipEstimator(model), sc.VelocityEkf(model)):
            run = sc.run_filter(scenario, estimator)
            errors = sc.prediction_errors(scenario, model, run, start=10.0)
            row += [sc.icr_error(run, scenario, start=10.0), errors['slip_position'].mean(),
                    errors['slip_heading'].mean()]
        row += [errors['noslip_position'].mean(), errors['noslip_heading'].mean()]
        rows.append(row)
    r = np.array(rows).mean(axis=0)
    print('sec. 4.2 1 Hz poses, 10 Hz encoders, speed-dependent ICRs (after 10 s)')
    print(f'  ICR error: pose-change EKF {r[0]:.3f} m, velocity-based EKF {r[3]:.3f} m')
    print(f'  2-s prediction position: {r[1]:.3f} m vs velocity-based {r[4]:.3f} m vs no-slip '
          f'{r[6]:.3f} m')
    print(f'  2-s prediction heading:  {r[2]:.3f} rad vs velocity-based {r[5]:.3f} rad vs '
          f'no-slip {r[7]:.3f} rad')


def cost():
    """Time one update and one prediction."""
    scenario = sc.abrupt_change(seed=0)
    model = AdaptiveIcr(scenario.track_width)
    est = SlipEstimator(model)
    k = 0
    times = []
    for t, pose in zip(scenario.pose_t, scenario.poses):
        while k < len(scenario.enc_t) and scenario.enc_t[k] <= t + 1e-9:
            est.add_step(scenario.enc_t[k], scenario.enc_left[k], scenario.enc_right[k],
                         scenario.enc_dt[k])
            k += 1
        start = time.perf_counter()
        est.add_pose(t, *pose)
        times.append(time.perf_counter() - start)
    left, right = hold_speeds(1.0, 2.0, 2.0, 0.05)
    pred = []
    for _ in range(200):
        start = time.perf_counter()
        predict_path(model, est.p, left, right, 0.05)
        pred.append(time.perf_counter() - start)
    print(f'cost: EKF update (1-s window, 100 Hz encoders) median '
          f'{1e3 * statistics.median(times):.2f} ms, p99 {1e3 * np.percentile(times, 99):.2f} ms;'
          f' 2-s prediction (40 steps) {1e3 * statistics.median(pred):.3f} ms')


if __name__ == '__main__':
    abrupt()
    low_rate()
    cost()
