"""
Short-horizon motion prediction: roll a slip model forward from track speeds or commands.

EKF paper sec. 3, eqs. 13-14; unknown future track speeds come from the commands through the drive
train of Fink & Stump (sec. III-B).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .command import track_setpoints
from .drivetrain import DriveTrain
from .kinematics import IcrParams
from .models import MotionModel


@dataclass(frozen=True)
class Prediction:
    """A predicted path: times ``t`` from 0 (s), ``poses`` in ``pose0``'s frame, speeds used."""

    t: np.ndarray
    poses: np.ndarray
    v_left: np.ndarray
    v_right: np.ndarray

    @property
    def end(self) -> np.ndarray:
        """Return the final pose ``(x, y, yaw)``."""
        return self.poses[-1]


def predict_path(model: MotionModel, p, v_left, v_right, dt: float,
                 pose0=(0.0, 0.0, 0.0)) -> Prediction:
    """Integrate the slip model over track speeds (m/s) held every ``dt`` s (EKF paper eq. 14)."""
    dt = float(dt)
    if not np.isfinite(dt) or dt <= 0.0:
        raise ValueError(f'dt must be a finite number > 0 s, got {dt!r}')
    v_left = np.asarray(v_left, dtype=float).ravel()
    v_right = np.asarray(v_right, dtype=float).ravel()
    if v_left.shape != v_right.shape:
        raise ValueError(f'v_left and v_right differ in length ({len(v_left)} vs '
                         f'{len(v_right)})')
    if not (np.all(np.isfinite(v_left)) and np.all(np.isfinite(v_right))):
        raise ValueError('track speeds must be finite')
    x, y, yaw = model.integrate(p, v_left * dt, v_right * dt, dt, pose0=pose0)
    poses = np.column_stack([np.concatenate([[pose0[0]], x]), np.concatenate([[pose0[1]], y]),
                             np.concatenate([[pose0[2]], yaw])])
    return Prediction(dt * np.arange(len(v_left) + 1), poses, v_left, v_right)


def hold_speeds(v_left: float, v_right: float, horizon: float, dt: float):
    """Return speed sequences that hold the current speeds for ``horizon`` s."""
    n = max(1, int(round(float(horizon) / float(dt))))
    return np.full(n, float(v_left)), np.full(n, float(v_right))


def predict_from_commands(model: MotionModel, p, drivetrain: DriveTrain, cmd_left, cmd_right,
                          dt: float, speeds0=(0.0, 0.0), pose0=(0.0, 0.0, 0.0)) -> Prediction:
    """
    Predict from commanded track speeds through the drive-train model, then the slip model.

    ``speeds0`` (m/s) is taken as the drive train's steady state (the last ``delay`` s of commands
    are not replayed: an approximation of at most one delay).
    """
    commands = np.column_stack([np.asarray(cmd_left, float), np.asarray(cmd_right, float)])
    if not np.all(np.isfinite(commands)):
        raise ValueError('commands must be finite')
    speeds = drivetrain.simulate(commands, dt, initial=np.asarray(speeds0, float))
    return predict_path(model, p, speeds[:, 0], speeds[:, 1], dt, pose0)


def commands_from_twist(v_x: float, w: float, icr: IcrParams, horizon: float, dt: float):
    """Hold a twist for ``horizon`` s as the nominal track commands (Martinez eqs. 10-11)."""
    left, right = track_setpoints(v_x, w, icr)
    return hold_speeds(float(left), float(right), horizon, dt)
