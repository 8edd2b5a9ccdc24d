"""
Planning with an identified model: the library behind ``plan_trajectory``.

Planning models and limits from a terrain file, plans executed on the dynamic simulator, the
Fink & Stump Table VI comparison, and plans as CSV or ``/cmd_vel`` bags. The planner is
:mod:`tracked_kinematics.core.plan`; see docs/tools/plan_trajectory.md.
"""

from __future__ import annotations

import csv
import io
import math
import sys

import numpy as np
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.command import CommandLimits
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.core.integration import relative_pose
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import model_class, model_names, MotionModel
from tracked_kinematics.core.plan import CANONICAL, canonical, path_deviation, Plan, Planner
from tracked_kinematics.core.sim.manoeuvres import fink_stump_sweep
from tracked_kinematics.core.sim.simulation import GroundTruth, Robot, simulate, TwistTable
from tracked_kinematics.offline.bags import BagWriter
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.outputs import Outputs
from tracked_kinematics.params import LIMIT_FIELDS, limits_from_values

# plan_trajectory's --model names: the registered models that declare one.
_MODEL_NAMES = {model_class(n).plan_name: n for n in model_names(aliases=False)
                if model_class(n).plan_name}
MODELS = tuple(_MODEL_NAMES)


# Models --------------------------------------------------------------------------------


def model_from_terrain(name: str, icr: IcrParams, values=None) -> tuple[MotionModel, np.ndarray]:
    """
    Build the planning model ``name`` (:data:`MODELS`) of a terrain file.

    Constant-ICR models take the file's ICRs (:meth:`~tracked_kinematics.core.models.
    MotionModel.from_icr`); others its ``identification.parameters.*`` (``identify_icr
    --model``). UsageError for a model whose parameters the file lacks.
    """
    model = ident.build_model(_MODEL_NAMES[name], icr.track_width)
    p = model.from_icr(icr)
    if p is not None or not model.n_params:
        return model, model.initial() if p is None else p
    names = model.param_names
    keys = [f'identification.parameters.{n}' for n in names]
    span = f'identification.parameters.{names[0]}..{names[-1]}'
    values = values or {}
    missing = [k for k in keys if k not in values]
    if missing:
        raise UsageError(f'--model {name} needs {span} in the terrain file (identify_icr '
                         f'--model {model.name} writes them)')
    try:
        p = np.array([float(values[k]) for k in keys])
    except (TypeError, ValueError):
        raise UsageError(f'{span} must be numbers') from None
    if not np.all(np.isfinite(p)):
        raise UsageError(f'{span} must be finite')
    return model, p


def limits_from(values, robot: Robot, max_track_speed=None, max_track_accel=None,
                source: str = ''):
    """
    Return the translator limits: command line, else terrain file, else drive train.

    Read as cmd_vel_translator reads them (:func:`tracked_kinematics.params.limits_from_values`);
    UsageError names a limit it would refuse, after ``source`` when given.
    """
    given = {param: values[param] for param in LIMIT_FIELDS if param in values}
    if max_track_speed is not None:
        given['max_track_speed'] = max_track_speed
    if max_track_accel is not None:
        given['max_track_accel'] = max_track_accel
    given.setdefault('max_track_speed', robot.drivetrain.max_speed)
    given.setdefault('max_track_accel', robot.drivetrain.max_accel)
    try:
        return limits_from_values(given)
    except InvalidParameters as err:
        raise UsageError(f'{source}: {err}' if source else str(err)) from None


# Execution on the dynamic simulator ----------------------------------------------------


def execute(robot: Robot, plan: Plan, table: TwistTable, start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Return the poses of the truth-like simulator driven by the plan, settling included."""
    settle = len(plan.poses) - len(plan.commands)
    commands = np.vstack([plan.commands, np.zeros((settle, 2))])
    return simulate(robot, commands, plan.dt, table=table, pose0=tuple(start)).pose


def final_error(poses, goal) -> tuple[float, float]:
    """Return the final position (m) and ``|heading|`` (rad) error of a path to a goal."""
    ex, ey, eth = relative_pose(*goal, *poses[-1])
    return math.hypot(ex, ey), abs(float(eth))


# Table VI ------------------------------------------------------------------------------


def identify_on_sweep(robot: Robot, table: TwistTable, dt: float = 0.02, seed: int = 0):
    """
    Return the planning models of the simulated vehicle, fitted on its Fink & Stump sweep.

    The sweep of sec. IV-B on the dynamic simulator, fitted on 1 s segments: ``{'ideal' |
    'effective' | 'icr' | 'general': (model, p)}``.
    """
    b = robot.vehicle.track_width
    commands = fink_stump_sweep(dt, b, robot.drivetrain.max_speed)
    run = simulate(robot, commands, dt, table=table,
                   ground_truth=GroundTruth(10.0, 0.002, 0.002),
                   rng=np.random.default_rng(seed))
    radius = robot.encoders.sprocket_radius
    rec = ident.Recording(run.t, run.joint_position[:, 0] * radius,
                          run.joint_position[:, 1] * radius, run.gt_t, run.gt_pose[:, 0],
                          run.gt_pose[:, 1], run.gt_pose[:, 2], name='sweep')
    segments = ident.build_segments([rec], 1.0)
    segments = segments.select(segments.travel >= 0.01)
    models = {}
    for short, name in _MODEL_NAMES.items():
        model = ident.build_model(name, b)
        models[short] = (model, ident.fit(model, segments, heading_weight=None, check=False).p
                         if model.n_params else model.initial())
    return models


def compare(robot: Robot, table: TwistTable, models, limits: CommandLimits, speed: float,
            dt: float = 0.02, names=CANONICAL, out=sys.stdout):
    """
    Plan every canonical trajectory with every model, execute it, tabulate (Table VI).

    Returns ``{model: {trajectory: (planned position error, executed position error, executed
    heading error, executed max path deviation, plan seconds)}}``.
    """
    results = {}
    for short, (model, p) in models.items():
        planner = Planner(model, p, robot.drivetrain, limits, dt=dt)
        results[short] = {}
        for name in names:
            ref = canonical(name, dt=dt, speed=speed)
            plan = planner.follow(ref)
            driven = execute(robot, plan, table)
            pos, yaw = final_error(driven, ref.goal)
            dev = float(np.max(path_deviation(driven, ref.path)))
            results[short][name] = (plan.position_error, pos, yaw, dev, plan.seconds)
    print(f'{"model":<10}' + ''.join(f'{n:>12}' for n in names)
          + f'{"mean":>9}{"max dev":>9}{"mean dev":>9}', file=out)
    print(f'{"":<10}' + ''.join(f'{"cm / deg":>12}' for _ in names)
          + f'{"cm":>9}{"m":>9}{"m":>9}', file=out)
    for short, row in results.items():
        cells = ''.join(f'{r[1] * 100:>6.1f} /{math.degrees(r[2]):>4.0f}' for r in row.values())
        mean = np.mean([r[1] for r in row.values()]) * 100
        devs = [r[3] for r in row.values()]
        print(f'{short:<10}{cells}{mean:>9.1f}{max(devs):>9.2f}{np.mean(devs):>9.2f}',
              file=out)
    return results


# Outputs -------------------------------------------------------------------------------


def csv_text(plan: Plan, icr: IcrParams) -> str:
    """Return ``t, left, right, v_x, w, x, y, yaw`` per command (setpoints, planned pose)."""
    v_x, w = plan.twists(icr)
    stream = io.StringIO(newline='')
    writer = csv.writer(stream)
    writer.writerow(['t', 'left', 'right', 'v_x', 'w', 'x', 'y', 'yaw'])
    for k, t in enumerate(plan.t):
        x, y, yaw = plan.poses[k]
        writer.writerow([f'{t:.4f}', f'{plan.commands[k, 0]:.6f}',
                         f'{plan.commands[k, 1]:.6f}', f'{v_x[k]:.6f}', f'{w[k]:.6f}',
                         f'{x:.6f}', f'{y:.6f}', f'{yaw:.6f}'])
    return stream.getvalue()


def write_csv(path, plan: Plan, icr: IcrParams, force: bool = False) -> None:
    """Write :func:`csv_text` to ``path`` through :class:`Outputs` (atomically)."""
    with Outputs(force=force) as out:
        out.add('--csv', path)
        out.write_text('--csv', csv_text(plan, icr))


def write_bag(path, plan: Plan, icr: IcrParams, storage: str = 'sqlite3',
              topic: str = '/cmd_vel') -> int:
    """Write the plan as geometry_msgs/Twist on ``topic`` to a new ``path``; return the count."""
    v_x, w = plan.twists(icr)
    with BagWriter(path, storage) as bag:
        for k, t in enumerate(plan.t):
            bag.write(topic, int(round(t * 1e9)), bag.twist(v_x[k], w[k]))
    return len(v_x)
