"""
One recording of a tracked vehicle: encoder travel and whichever references it has.

Bags are read into it (:mod:`tracked_kinematics.offline.bags`), the calibration drive records
into it, and every fitter of :mod:`.identify` takes it. It is checked once, when built.
"""

from __future__ import annotations

from dataclasses import dataclass, KW_ONLY

import numpy as np

# Streams: (times, values...), whether finite and strictly increasing, value columns.
_STREAMS = (
    (('enc_t', 'left', 'right'), True, 1),
    (('speed_t', 'speeds'), False, 2),
    (('gt_t', 'gt_x', 'gt_y', 'gt_yaw'), True, 1),
    (('gnss_t', 'gnss_x', 'gnss_y'), True, 1),
    (('command_t', 'commands'), False, 2),
    (('cmd_vel_t', 'cmd_vel'), False, 2),
)
_GYRO = ('gyro_rate', 'gyro_yaw', 'gyro_quaternion', 'gyro_quaternion_cov0', 'gyro_omega')
_WIDTHS = {'gyro_quaternion': 4, 'gyro_omega': 3}


@dataclass(frozen=True)
class Recording:
    """
    One continuous log, times in seconds on one clock; absent streams are None.

    Attributes
    ----------
    enc_t : ndarray, shape (N,)
        Encoder sample times, s, finite and strictly increasing.
    left, right : ndarray, shape (N,)
        Cumulative nominal travel of each track at those times, m (any offset), finite.
    gt_t, gt_x, gt_y, gt_yaw : ndarray, shape (M,)
        Poses of base_link in a fixed frame (ground truth or a pose reference): times (s,
        strictly increasing), m, m, rad; finite. The fields below are keyword-only.
    speed_t, speeds : ndarray, shape (S,) and (S, 2)
        Nominal track speeds (left, right) the encoders report (joint velocities), m/s.
    gyro_t : ndarray, shape (K,)
        Gyro stamps, s, finite and strictly increasing.
    gyro_rate : ndarray, shape (K,)
        Yaw rates, rad/s (counter-clockwise positive).
    gyro_yaw : ndarray, shape (K,)
        Yaw angles of the IMU's orientation estimate, rad.
    gyro_quaternion, gyro_quaternion_cov0 : ndarray, shape (K, 4) and (K,)
        The IMU's orientation ``(x, y, z, w)`` and ``orientation_covariance[0]`` (-1: none).
    gyro_omega : ndarray, shape (K, 3)
        The IMU's ``angular_velocity`` (x, y, z) as it came, in its own frame, rad/s, where
        ``gyro_rate`` is the heading rate read from it (a node's recording: for its bag).
    gnss_t, gnss_x, gnss_y : ndarray, shape (P,)
        Positions in a local plane (GNSS): times (s, strictly increasing), m, m; finite.
    command_t, commands : ndarray, shape (C,) and (C, 2)
        Track setpoints (left, right), m/s, each holding until the next.
    cmd_vel_t, cmd_vel : ndarray, shape (D,) and (D, 2)
        Body twists ``(v, w)`` commanded on cmd_vel: m/s, rad/s.
    t0_ns : int
        Stamp of time 0, ns (a bag read: its first encoder sample; a node's recording: its
        earliest stamp), else 0.
    name : str
        Where it came from (a bag path), for reports.
    gyro_topic : str
        The IMU topic the gyro stream was read from, for reports ('' when none was read; set
        with no gyro stream when a topic found in the bag had no messages).

    """

    enc_t: np.ndarray
    left: np.ndarray
    right: np.ndarray
    gt_t: np.ndarray | None = None
    gt_x: np.ndarray | None = None
    gt_y: np.ndarray | None = None
    gt_yaw: np.ndarray | None = None
    _: KW_ONLY
    speed_t: np.ndarray | None = None
    speeds: np.ndarray | None = None
    gyro_t: np.ndarray | None = None
    gyro_rate: np.ndarray | None = None
    gyro_yaw: np.ndarray | None = None
    gyro_quaternion: np.ndarray | None = None
    gyro_quaternion_cov0: np.ndarray | None = None
    gyro_omega: np.ndarray | None = None
    gnss_t: np.ndarray | None = None
    gnss_x: np.ndarray | None = None
    gnss_y: np.ndarray | None = None
    command_t: np.ndarray | None = None
    commands: np.ndarray | None = None
    cmd_vel_t: np.ndarray | None = None
    cmd_vel: np.ndarray | None = None
    t0_ns: int = 0
    name: str = ''
    gyro_topic: str = ''

    def __post_init__(self):
        for names, finite, columns in _STREAMS:
            self._check(names, finite, columns, increasing=finite)
        given = [n for n in _GYRO if getattr(self, n) is not None]
        if self.gyro_t is None:
            if given:
                raise ValueError(f'{given[0]} needs gyro_t')
            return
        if self.gyro_rate is None and self.gyro_yaw is None:
            raise ValueError('give gyro_rate or gyro_yaw with gyro_t')
        self._check(('gyro_t', *given), False, 1, increasing=True)

    def _check(self, names, finite, columns, increasing):
        values = [getattr(self, n) for n in names]
        if names[0] != 'enc_t' and all(v is None for v in values):
            return
        if any(v is None for v in values):
            raise ValueError(f'give {", ".join(names)} together')
        arrays = [np.asarray(v, dtype=float) for v in values]
        n = len(arrays[0]) if arrays[0].ndim == 1 else -1
        widths = [_WIDTHS.get(name, columns) if k else 1
                  for k, name in enumerate(names)]
        if any(a.shape != ((n,) if w == 1 else (n, w)) for a, w in zip(arrays, widths)):
            expected = ', '.join('(N,)' if w == 1 else f'(N, {w})' for w in widths)
            raise ValueError(f'{", ".join(names)} must have the shapes {expected}, got '
                             + ', '.join(str(a.shape) for a in arrays))
        for name, a in zip(names, arrays):
            if (finite or (increasing and name == names[0])) and not np.all(np.isfinite(a)):
                raise ValueError(f'{name} has non-finite values')
            object.__setattr__(self, name, a)
        if increasing and np.any(np.diff(arrays[0]) <= 0.0):
            raise ValueError(f'{names[0]} must be strictly increasing')

    @property
    def pose(self):
        """``(t, x, y, yaw)`` of the pose stream, or None."""
        return None if self.gt_t is None else (self.gt_t, self.gt_x, self.gt_y, self.gt_yaw)

    @property
    def positions(self):
        """``(t, x, y)`` of the GNSS stream, or None."""
        return None if self.gnss_t is None else (self.gnss_t, self.gnss_x, self.gnss_y)

    @property
    def duration(self) -> float:
        """Time covered by both encoders and ground truth, s."""
        if self.gt_t is None or not (len(self.enc_t) and len(self.gt_t)):
            return 0.0
        start = max(self.enc_t[0], self.gt_t[0])
        end = min(self.enc_t[-1], self.gt_t[-1])
        return float(max(0.0, end - start))

    def stamps_ns(self, t) -> np.ndarray:
        """Return the stamps (int64 ns) of times ``t`` (s) of this recording."""
        return np.round(np.asarray(t, dtype=float) * 1e9).astype(np.int64) + self.t0_ns

    def track_speeds(self):
        """
        Return the measured track speeds: the encoders' own, else the travel differentiated.

        Returns
        -------
        t : ndarray, shape (S,)
            s; differentiated travel is stamped at the midpoints of the encoder intervals.
        speeds : ndarray, shape (S, 2)
            Nominal (left, right) track speeds, m/s.

        Raises
        ------
        ValueError
            Without speeds and with fewer than two encoder samples.

        """
        if self.speed_t is not None:
            return self.speed_t, self.speeds
        if len(self.enc_t) < 2:
            raise ValueError(f'{self.name}: fewer than two encoder samples')
        ns = np.round(self.enc_t * 1e9)   # differenced in whole ns, as stamped
        dt = np.diff(ns) * 1e-9
        return (0.5 * (ns[1:] + ns[:-1]) * 1e-9,
                np.column_stack([np.diff(self.left) / dt, np.diff(self.right) / dt]))


def from_stamped_rows(encoder=(), pose=(), imu=(), cmd=(), name: str = '') -> Recording:
    """
    Build a recording from rows ``(stamp_ns, values...)`` as a node records them.

    ``encoder`` rows ``(t, left, right)``, ``pose`` rows ``(t, x, y, yaw)``, ``imu`` rows
    ``(t, yaw_rate, qx, qy, qz, qw, orientation_covariance0)``, optionally followed by the
    message's ``angular_velocity`` ``(wx, wy, wz)`` (``gyro_omega``; every row alike),
    ``cmd`` rows ``(t, v, w)`` (cmd_vel).
    Time 0 is the earliest stamp; a stream without rows is None (the encoders: empty). The
    sensor rows are sorted by stamp, the first of equal stamps kept (as a bag is read).
    """
    def split(rows, width, sort=True):
        if not len(rows):
            return np.zeros(0, np.int64), np.zeros((0, width))
        t = np.array([r[0] for r in rows], dtype=np.int64)
        values = np.array([r[1:] for r in rows], dtype=float).reshape(len(rows), width)
        if sort and np.any(np.diff(t) <= 0):
            order = np.argsort(t, kind='stable')
            keep = order[np.concatenate([[True], np.diff(t[order]) > 0])]
            t, values = t[keep], values[keep]
        return t, values

    imu_width = len(imu[0]) - 1 if len(imu) else 6
    if imu_width not in (6, 9):
        raise ValueError(f'imu rows have 7 or 10 values, got {imu_width + 1}')
    streams = [split(encoder, 2), split(pose, 3), split(imu, imu_width),
               split(cmd, 2, sort=False)]
    firsts = [int(t[0]) for t, _ in streams if len(t)]
    t0 = min(firsts) if firsts else 0
    (enc_t, enc), (pose_t, poses), (imu_t, imu_values), (cmd_t, cmds) = [
        ((t - t0) * 1e-9, v) for t, v in streams]
    parts = {}
    if len(pose_t):
        parts.update(gt_t=pose_t, gt_x=poses[:, 0], gt_y=poses[:, 1], gt_yaw=poses[:, 2])
    if len(imu_t):
        parts.update(gyro_t=imu_t, gyro_rate=imu_values[:, 0],
                     gyro_quaternion=imu_values[:, 1:5], gyro_quaternion_cov0=imu_values[:, 5],
                     gyro_omega=imu_values[:, 6:9] if imu_width == 9 else None)
    if len(cmd_t):
        parts.update(cmd_vel_t=cmd_t, cmd_vel=cmds)
    return Recording(enc_t, enc[:, 0], enc[:, 1], t0_ns=t0, name=name, **parts)
