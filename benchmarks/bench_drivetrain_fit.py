"""
Benchmark: drive-train identification of issue 8 (``identify_drivetrain``).

Prints, for 60 s and 10 min of manual-like driving (the simulator's ``mixed`` manoeuvres,
setpoints at 50 Hz, encoder speeds at 100 Hz with 1 mm/s white noise):
- the fit time and the recovered delay, acceleration limit and loop of the Auriga-alpha
  (first-order loop) and the Packbot (Table II PID + DC motor; gains fitted from a start
  far from Table II's);
- ``identify_drivetrain`` end to end (bag reading included) on a 60 s simulated bag.
"""

import contextlib
from dataclasses import replace
import io
import tempfile
import time

import numpy as np

from tracked_kinematics.core.identify import fit_drivetrain, Recording
from tracked_kinematics.core.sim.manoeuvres import manoeuvre
from tracked_kinematics.offline.bag_simulation import simulate_bag
from tracked_kinematics.offline.cli import identify_drivetrain as cli
from tracked_kinematics.offline.vehicle_file import load_vehicle

RATE, SETPOINT_RATE, NOISE = 100.0, 50.0, 0.001


def drive_data(robot, duration, seed=0):
    """Commanded and measured speeds of a simulated run of ``robot``."""
    rng = np.random.default_rng(seed)
    veh = robot.vehicle
    cmd = manoeuvre('mixed', duration, 1.0 / SETPOINT_RATE, veh.track_width,
                    veh.max_track_speed, rng)
    n = int(round(duration * RATE)) + 1
    held = np.minimum(np.arange(n) // int(RATE / SETPOINT_RATE), len(cmd) - 1)
    speeds = robot.drivetrain.simulate(cmd[held], 1.0 / RATE)
    speeds = speeds + rng.normal(0.0, NOISE, size=speeds.shape)
    t = np.arange(n) / RATE
    travel = np.vstack([np.zeros(2), np.cumsum(0.5 * (speeds[1:] + speeds[:-1]) / RATE, axis=0)])
    return Recording(t, travel[:, 0], travel[:, 1], speed_t=t, speeds=speeds,
                     command_t=np.arange(len(cmd)) / SETPOINT_RATE, commands=cmd)


def describe(drive):
    """Return the parameters of a drive train on one line."""
    loop = drive.loop
    text = f'delay {drive.delay:.3f} s, max_accel {drive.max_accel:.3f} m/s^2'
    if hasattr(loop, 'time_constant'):
        return text + f', T {loop.time_constant:.4f} s'
    if hasattr(loop, 'kp'):
        return text + f', kp {loop.kp:.2f}, ki {loop.ki:.3f}, kd {loop.kd:.3f}'
    return text


def main():
    """Time the fits and print the figures."""
    for name, loop in (('auriga_alpha', 'first_order'), ('packbot', 'pid_dc_motor')):
        robot = load_vehicle(name).robot
        print(f'{name} truth: {describe(robot.drivetrain)}')
        # The PID fit starts from gains far from Table II's (the motor constants are fixed).
        base = None
        if loop == 'pid_dc_motor':
            base = replace(robot.drivetrain, loop=replace(robot.drivetrain.loop, kp=30.0,
                                                          ki=0.3, kd=1.5))
            print(f'  start: {describe(base)}')
        for duration in (60.0, 600.0):
            data = drive_data(robot, duration)
            start = time.perf_counter()
            fit = fit_drivetrain(data, loop=loop, base=base)
            seconds = time.perf_counter() - start
            print(f'  {duration:4.0f} s of data, {loop:<13} fit in {seconds:6.2f} s '
                  f'({fit.delays_fitted} delays, {fit.nfev} simulations): '
                  f'{describe(fit.drivetrain)}; rms {1000 * fit.rms:.2f} mm/s '
                  f'(commands as speeds {1000 * fit.rms_commands:.0f} mm/s)')
    with tempfile.TemporaryDirectory() as tmp:
        sim = simulate_bag(f'{tmp}/run', 'auriga_alpha', duration=60.0, seed=1)
        start = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            radius = load_vehicle('auriga_alpha').robot.encoders.sprocket_radius
            status = cli.main([str(sim.bag), '-o', f'{tmp}/d.yaml',
                               '--sprocket-radius', str(radius)])
        assert status == 0, status
        print(f'identify_drivetrain on a 60 s bag ({sum(sim.messages.values())} messages), '
              f'end to end: {time.perf_counter() - start:.2f} s')


if __name__ == '__main__':
    main()
