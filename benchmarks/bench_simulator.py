"""
Benchmark: the simulator of issue 7.

Prints, best of a few runs:
- the 21 x 21 ICR map (stationary solver over 441 speed pairs) of the shipped vehicles, with
  and without load transfer;
- the twist table build and the simulation speed (simulated seconds per wall second);
- the bag writing rate per storage, messages per second;
- simulate_bag end to end for the demo's 3 minutes of driving.
Goal (issue 7): the simulator's share of the demo takes a few seconds.
"""

from dataclasses import replace
import tempfile

import numpy as np
from timing import best_of

from tracked_kinematics.core.sim.icr_maps import icr_map
from tracked_kinematics.core.sim.manoeuvres import manoeuvre
from tracked_kinematics.core.sim.simulation import GroundTruth, simulate, TwistTable
from tracked_kinematics.offline.bag_simulation import simulate_bag, write_run
from tracked_kinematics.offline.vehicle_file import load_vehicle

REPEATS = 3


def main():
    """Time every stage and print the figures."""
    auriga = load_vehicle('auriga_alpha').robot
    packbot = load_vehicle('packbot').robot
    vehicles = {'auriga_alpha (load transfer)': auriga.vehicle,
                'auriga_alpha (quasi-static)': replace(auriga.vehicle, com_height=0.0),
                'packbot (load transfer)': packbot.vehicle}
    for label, vehicle in vehicles.items():
        seconds, the_map = best_of(lambda v=vehicle: icr_map(v, 21), REPEATS)
        print(f'bench_simulator: ICR map 21 x 21, {label}: {seconds:.3f} s '
              f'({the_map.failed} failed)')

    table_s, table = best_of(lambda: TwistTable(auriga.vehicle), REPEATS)
    print(f'bench_simulator: twist table (144 directions x 8 speeds), auriga_alpha: '
          f'{table_s:.3f} s')
    dt = 0.01
    for duration in (180.0, 3600.0):
        commands = manoeuvre('mixed', duration, dt, 0.42, 1.0, np.random.default_rng(0))
        sim_s, run = best_of(lambda c=commands: simulate(
            auriga, c, dt, table, GroundTruth(10.0, 0.002, 0.002), np.random.default_rng(0)),
            REPEATS)
        print(f'bench_simulator: simulate {duration:.0f} s at 100 Hz: {sim_s:.3f} s '
              f'({duration / sim_s:,.0f} simulated s per wall s)')

    commands = manoeuvre('mixed', 60.0, dt, 0.42, 1.0, np.random.default_rng(0))
    run = simulate(auriga, commands, dt, table, GroundTruth(10.0), np.random.default_rng(0))
    with tempfile.TemporaryDirectory() as tmp:
        for storage in ('sqlite3', 'mcap', 'rosbag1'):
            paths = iter(f'{tmp}/{storage}{k}' + ('.bag' if storage == 'rosbag1' else '')
                         for k in range(REPEATS))
            seconds, counts = best_of(lambda s=storage: write_run(next(paths), run, s, 50.0),
                                      REPEATS)
            total = sum(counts.values())
            print(f'bench_simulator: write bag ({storage}), 60 s of data, {total} messages: '
                  f'{seconds:.2f} s ({total / seconds:,.0f} messages/s)')
        names = iter(f'{tmp}/demo{k}' for k in range(REPEATS))
        seconds, result = best_of(lambda: simulate_bag(next(names), 'auriga_alpha',
                                                       duration=180.0), REPEATS)
        print(f'bench_simulator: simulate_bag auriga_alpha, 180 s mixed, end to end: '
              f'{seconds:.2f} s ({sum(result.messages.values())} messages); goal: a few s')


if __name__ == '__main__':
    main()
