"""
Benchmark: trajectory generation (issue 9). Prints the figures; goals in brackets.

1. Plan time per canonical trajectory (Table V and ours) on the Packbot-like vehicle, with
   each planning model, best of 3 runs. [< 1 s each]
2. Plan time to goal poses (``plan_to``) with the ICR model.
3. Table VI on the simulator: models fitted on a simulated Fink & Stump sweep, every
   canonical trajectory planned with each and executed on the dynamic simulator; final
   pose error and max path deviation per model (``plan_trajectory --compare``).
"""

import numpy as np
from timing import best_of
from tracked_kinematics.core.plan import CANONICAL, canonical, Planner
from tracked_kinematics.core.sim.simulation import TwistTable
from tracked_kinematics.offline.planning import compare, identify_on_sweep, limits_from
from tracked_kinematics.offline.vehicle_file import load_vehicle


def main():
    """Run the benchmarks and print their figures."""
    robot = load_vehicle('packbot').robot
    table = TwistTable(robot.vehicle)
    models = identify_on_sweep(robot, table)
    limits = limits_from({}, robot)
    print('bench_planning: plan time per canonical trajectory, packbot, 1 m/s (best of 3) '
          '[goal < 1 s]')
    print(f'{"model":<10}' + ''.join(f'{n:>12}' for n in CANONICAL))
    worst = 0.0
    for short, (model, p) in models.items():
        planner = Planner(model, p, robot.drivetrain, limits)
        cells = []
        for name in CANONICAL:
            ref = canonical(name, speed=1.0)
            seconds, plan = best_of(lambda: planner.follow(ref), 3)
            worst = max(worst, seconds)
            cells.append(f'{seconds:>7.2f} s{"" if plan.success else "!":<3}')
        print(f'{short:<10}' + ''.join(cells))
    print(f'slowest {worst:.2f} s (! marks a plan that missed its tolerance)')
    planner = Planner(*models['icr'], robot.drivetrain, limits)
    goals = [((2.0, 1.0, 0.5), 4.0), ((-1.0, 0.5, 0.0), 4.0), ((0.0, 0.0, 1.5), 3.0),
             ((4.0, -2.0, -1.0), 5.0)]
    for goal, horizon in goals:
        seconds, plan = best_of(lambda: planner.plan_to(goal, horizon), 3)
        print(f'plan_to {goal} in {horizon:g} s: {seconds:.2f} s, {plan.nfev} predictions, '
              f'{"ok" if plan.success else "FAILED"} ({plan.position_error * 100:.1f} cm)')
    print('Table VI on the simulated packbot (executed with the dynamic model):')
    compare(robot, table, models, limits, 1.0)
    np.set_printoptions(precision=4, suppress=True)
    for short, (_, p) in models.items():
        print(f'  {short:<10}{p}')


if __name__ == '__main__':
    main()
