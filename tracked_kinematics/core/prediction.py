"""
Short-horizon motion prediction: roll a slip model forward from track speeds or commands.

The EKF paper (sec. 3, eqs. 13-14) predicts the next seconds of motion by integrating the
slip model over a sequence of track speeds with the current parameter estimate. Where the
future track speeds are not known, they come from the commands through the drive-train
model of Fink & Stump (sec. III-B; :class:`~tracked_kinematics.core.drivetrain.DriveTrain`),
which is what lets a planner or a safety monitor predict from ``cmd_vel``.
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
    """
    A predicted path.

    Attributes
    ----------
    t : ndarray, shape (N + 1,)
        Time from the start, s (``t[0] = 0``).
    poses : ndarray, shape (N + 1, 3)
        ``(x, y, yaw)`` in the frame of ``pose0``: m, m, rad (yaw unwrapped).
    v_left, v_right : ndarray, shape (N,)
        Measured (nominal) track speeds used over each step, m/s.

    """

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
    """
    Integrate the slip model over a sequence of track speeds (EKF paper eq. 14).

    Parameters
    ----------
    model : MotionModel
        Slip model; ``p`` its parameters.
    p : array_like
        Parameter vector (e.g. :attr:`SlipEstimator.p`).
    v_left, v_right : array_like, shape (N,)
        Nominal track speeds held over each step, m/s.
    dt : float
        Step, s (> 0).
    pose0 : tuple of float
        Start pose ``(x, y, yaw)``.

    """
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

    Parameters
    ----------
    model, p
        Slip model and its parameters.
    drivetrain : DriveTrain
        Delay, acceleration limit and speed loop (Fink & Stump sec. III-B).
    cmd_left, cmd_right : array_like, shape (N,)
        Commanded nominal track speeds every ``dt`` (held in between), m/s.
    dt : float
        Step, s.
    speeds0 : tuple of float
        Track speeds now, taken as the drive train's steady state (the commands of the
        last ``delay`` seconds are not replayed: an approximation of at most one delay).
    pose0 : tuple of float
        Start pose.

    """
    commands = np.column_stack([np.asarray(cmd_left, float), np.asarray(cmd_right, float)])
    if not np.all(np.isfinite(commands)):
        raise ValueError('commands must be finite')
    speeds = drivetrain.simulate(commands, dt, initial=np.asarray(speeds0, float))
    return predict_path(model, p, speeds[:, 0], speeds[:, 1], dt, pose0)


def commands_from_twist(v_x: float, w: float, icr: IcrParams, horizon: float, dt: float):
    """
    Hold a body-twist command for ``horizon`` s as nominal track commands.

    The inverse kinematics (Martinez eqs. 10-11) with the current ICR estimate and its
    scales gives the nominal track setpoints ``cmd_vel_translator`` would command.
    """
    left, right = track_setpoints(v_x, w, icr)
    return hold_speeds(float(left), float(right), horizon, dt)
