"""
Sensor models of the simulator: a yaw-rate gyro and a GNSS receiver, vectorised.

What robots without motion capture carry. Both take the simulated truth as plain arrays
and a ``numpy.random.Generator``, and return what the sensor would report, stamped as it
would stamp it. Pure numpy/scipy; the bag writer and the live simulator node wrap the
results into sensor_msgs/Imu and sensor_msgs/NavSatFix.

API
---
``GyroModel(rate=100.0, bias=0.0, noise_std=0.0, bias_walk=0.0, latency=0.0, scale=1.0,
saturation=inf)``
    A z-axis rate gyro; all SI (Hz, rad/s, rad/s/sqrt(s), s).
``gyro_samples(times_true, yaw_rate_true, model, rng) -> (stamps, z_rate)``
    Gyro readings at ``model.rate`` over the span of ``times_true``.
``GnssModel(rate=5.0, noise_std=2.0, correlation_time=0.0, latency=0.0, dropout=0.0,
antenna_x=0.0, antenna_y=0.0, status=0)``
    A GNSS receiver reporting the antenna's horizontal position.
``gnss_samples(times_true, x, y, theta, model, rng) -> (stamps, east, north, status)``
    Fixes at ``model.rate`` in the local plane; ``status`` is NavSatStatus' (-1: no fix,
    then ``east``/``north`` are NaN).
``GyroStream(model, rng)``, ``GnssStream(model, rng)``
    The same models fed incrementally (a live node): ``push(times, values...)`` appends
    truth and returns the readings that became due, with the same statistics as the batch
    functions.
``GeoOrigin``, ``geodetic_to_enu``, ``enu_to_geodetic``
    Local plane <-> latitude/longitude (re-exported from :mod:`..geodesy`, where
    identification finds them too).

Conventions
-----------
- Truth: ``times_true`` increasing (s); a rate ``yaw_rate_true[k]`` is held from
  ``times_true[k]`` to ``times_true[k + 1]`` (the simulator's steps; length N or N - 1),
  poses are interpolated linearly between samples. Before the first and after the last
  sample the robot is taken as at rest there.
- Latency: a reading stamped ``s`` shows the truth of ``s - latency`` (a late stamp,
  positive latency; what the identification estimates as ``imu_delay``).
- A gyro reading is the mean true rate over one sample period centred on ``s - latency``
  (an integrating gyro), so that summing ``z_rate / rate`` recovers the heading change
  exactly when noise and bias are zero. Then
  ``z = clip(scale * mean_rate + bias_k + noise_std * N(0, 1), -saturation, saturation)``,
  ``bias_k = bias + bias_walk * sqrt(1 / rate) * (sum of k standard normals)``.
- GNSS noise is white (``correlation_time`` 0) or first-order Gauss-Markov with time
  constant ``correlation_time`` and the same standard deviation ``noise_std`` per axis
  (standalone receivers wander slowly; RTK is near white at centimetres).
- Stamps are ``times_true[0] + k / rate``.

A short example:
>>> rng = np.random.default_rng(0)
>>> t = np.arange(0.0, 10.0, 0.01)
>>> stamps, z = gyro_samples(t, np.full(t.size, 0.5), GyroModel(bias=0.01), rng)

"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy.signal import lfilter

from .._checks import require_numbers
from ..geodesy import enu_to_geodetic, geodetic_to_enu, GeoOrigin

__all__ = ['GeoOrigin', 'GnssModel', 'GnssStream', 'GyroModel', 'GyroStream',
           'enu_to_geodetic', 'geodetic_to_enu', 'gnss_samples', 'gyro_samples',
           'STATUS_NO_FIX', 'STATUS_FIX', 'STATUS_SBAS_FIX', 'STATUS_GBAS_FIX']

# sensor_msgs/NavSatStatus.status values.
STATUS_NO_FIX = -1
STATUS_FIX = 0
STATUS_SBAS_FIX = 1
STATUS_GBAS_FIX = 2


@dataclass(frozen=True, slots=True)
class GyroModel:
    """
    A z-axis rate gyro.

    Attributes
    ----------
    rate : float
        Readings per second, Hz.
    bias : float
        Constant offset at the first reading, rad/s.
    noise_std : float
        Standard deviation of the white noise of one reading, rad/s.
    bias_walk : float
        Random walk of the bias, rad/s/sqrt(s) (0: a constant bias).
    latency : float
        A reading stamped ``s`` shows the truth at ``s - latency``, s (may be negative).
    scale : float
        Scale-factor of the gyro (1: exact).
    saturation : float
        Largest magnitude the gyro reports, rad/s (inf: none); readings are clipped.

    """

    rate: float = 100.0
    bias: float = 0.0
    noise_std: float = 0.0
    bias_walk: float = 0.0
    latency: float = 0.0
    scale: float = 1.0
    saturation: float = math.inf

    def __post_init__(self):
        # The other fields are checked where they enter (simulate_bag's --imu-* options,
        # tracked_simulator's gyro_* parameters); no option sets the scale.
        require_numbers(self, positive=('scale',))


@dataclass(frozen=True, slots=True)
class GnssModel:
    """
    A GNSS receiver: horizontal position of its antenna.

    Attributes
    ----------
    rate : float
        Fixes per second, Hz.
    noise_std : float
        Standard deviation of the position error per horizontal axis, m (1-3 standalone,
        0.01-0.03 RTK).
    correlation_time : float
        Time constant of the error (first-order Gauss-Markov), s; 0 for white noise.
    latency : float
        A fix stamped ``s`` shows the position at ``s - latency``, s.
    dropout : float
        Probability that a fix is missing (reported with ``STATUS_NO_FIX``), in [0, 1].
    antenna_x, antenna_y : float
        Antenna position in base_link, m.
    status : int
        NavSatStatus of a good fix: 0 (FIX), 1 (SBAS), 2 (GBAS, e.g. RTK).

    """

    rate: float = 5.0
    noise_std: float = 2.0
    correlation_time: float = 0.0
    latency: float = 0.0
    dropout: float = 0.0
    antenna_x: float = 0.0
    antenna_y: float = 0.0
    status: int = STATUS_FIX


# Truth handling -------------------------------------------------------------------------

def _truth_times(times_true):
    t = np.asarray(times_true, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f'times_true must have shape (N >= 2,), got {t.shape}')
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError('times_true must be finite and strictly increasing')
    return t


def _heading_of_rates(t, yaw_rate):
    """Cumulative heading at ``t`` of rates held over each step (zero-order hold)."""
    w = np.asarray(yaw_rate, dtype=float)
    if w.shape not in ((t.size,), (t.size - 1,)):
        raise ValueError(f'yaw_rate_true must have shape ({t.size},) or ({t.size - 1},), '
                         f'got {w.shape}')
    if not np.all(np.isfinite(w)):
        raise ValueError('yaw_rate_true must be finite')
    return np.r_[0.0, np.cumsum(w[:t.size - 1] * np.diff(t))]


def _stamps(first, last, rate, start_index=0):
    """``first + k / rate`` for k >= start_index up to ``last``."""
    n_end = int(math.floor((last - first) * rate + 1e-9)) + 1
    return first + np.arange(start_index, max(n_end, start_index)) / rate


def _gyro_readings(stamps, t, heading, model, bias0, rng):
    """Return the readings at ``stamps`` and the bias after the last one (for a stream)."""
    n = stamps.size
    period = 1.0 / model.rate
    centre = stamps - model.latency
    mean_rate = (np.interp(centre + 0.5 * period, t, heading)
                 - np.interp(centre - 0.5 * period, t, heading)) / period
    bias = np.full(n, bias0)
    next_bias = bias0
    if model.bias_walk > 0 and n:
        steps = rng.normal(0.0, model.bias_walk * math.sqrt(period), n)
        walk = np.cumsum(steps)
        bias = bias0 + np.r_[0.0, walk[:-1]]
        next_bias = bias0 + walk[-1]
    z = model.scale * mean_rate + bias
    if model.noise_std > 0 and n:
        z = z + rng.normal(0.0, model.noise_std, n)
    return np.clip(z, -model.saturation, model.saturation), next_bias


def gyro_samples(times_true, yaw_rate_true, model: GyroModel, rng: np.random.Generator):
    """
    Gyro readings of a simulated run.

    Parameters
    ----------
    times_true : array_like, shape (N,)
        Truth sample times, s, strictly increasing.
    yaw_rate_true : array_like, shape (N,) or (N - 1,)
        True yaw rate held over each step, rad/s (``Run.twist[:, 2]``).
    model : GyroModel
        The gyro.
    rng : numpy.random.Generator
        Source of noise and bias walk.

    Returns
    -------
    stamps : ndarray, shape (M,)
        Reading stamps, s: ``times_true[0] + k / model.rate`` up to ``times_true[-1]``.
    z_rate : ndarray, shape (M,)
        Angular velocity about z, rad/s (REP-103: counter-clockwise positive).

    """
    t = _truth_times(times_true)
    heading = _heading_of_rates(t, yaw_rate_true)
    stamps = _stamps(t[0], t[-1], model.rate)
    z, _ = _gyro_readings(stamps, t, heading, model, model.bias, rng)
    return stamps, z


def _gnss_noise(n, model, rng, state=None):
    """Per-axis errors, shape (n, 2), and the last error (for a stream)."""
    if model.noise_std <= 0 or n == 0:
        return np.zeros((n, 2)), state
    white = rng.normal(0.0, model.noise_std, (n, 2))
    if model.correlation_time <= 0:
        return white, state
    phi = math.exp(-1.0 / (model.rate * model.correlation_time))
    gain = math.sqrt(1.0 - phi * phi)
    if state is None:   # stationary start: the first error has the full variance
        state, white = white[0], white[1:]
        head = [state[None, :]]
    else:
        head = []
    # e_k = phi e_(k-1) + gain w_k, from e_(-1) = state.
    rest = lfilter([gain], [1.0, -phi], white, axis=0, zi=(phi * state)[None, :])[0]
    errors = np.vstack(head + [rest])
    return errors, errors[-1].copy()


def _gnss_fixes(stamps, t, x, y, theta, model, rng, state=None):
    at = stamps - model.latency
    px, py, pth = (np.interp(at, t, v) for v in (x, y, theta))
    east = px + np.cos(pth) * model.antenna_x - np.sin(pth) * model.antenna_y
    north = py + np.sin(pth) * model.antenna_x + np.cos(pth) * model.antenna_y
    errors, state = _gnss_noise(stamps.size, model, rng, state)
    east, north = east + errors[:, 0], north + errors[:, 1]
    status = np.full(stamps.size, model.status, dtype=np.int8)
    if model.dropout > 0 and stamps.size:
        lost = rng.uniform(0.0, 1.0, stamps.size) < model.dropout
        status[lost] = STATUS_NO_FIX
        east[lost] = np.nan
        north[lost] = np.nan
    return east, north, status, state


def _pose_arrays(t, x, y, theta):
    arrays = [np.asarray(v, dtype=float) for v in (x, y, theta)]
    for name, v in zip(('x', 'y', 'theta'), arrays):
        if v.shape != t.shape:
            raise ValueError(f'{name} must have shape {t.shape}, got {v.shape}')
        if not np.all(np.isfinite(v)):
            raise ValueError(f'{name} must be finite')
    return arrays


def gnss_samples(times_true, x, y, theta, model: GnssModel, rng: np.random.Generator):
    """
    GNSS fixes of a simulated run, in the local east-north plane.

    Parameters
    ----------
    times_true : array_like, shape (N,)
        Truth sample times, s, strictly increasing.
    x, y, theta : array_like, shape (N,)
        True pose of base_link in the local plane (x east, y north), m, m, rad
        (theta continuous, ``Run.pose.T``).
    model : GnssModel
        The receiver.
    rng : numpy.random.Generator
        Source of noise and dropouts.

    Returns
    -------
    stamps : ndarray, shape (M,)
        Fix stamps, s.
    east, north : ndarray, shape (M,)
        Antenna position, m; NaN where there is no fix.
    status : ndarray of int8, shape (M,)
        NavSatStatus status: ``model.status`` or ``STATUS_NO_FIX``.

    Notes
    -----
    Convert to NavSatFix latitude/longitude with :func:`enu_to_geodetic`.

    """
    t = _truth_times(times_true)
    x, y, theta = _pose_arrays(t, x, y, theta)
    stamps = _stamps(t[0], t[-1], model.rate)
    east, north, status, _ = _gnss_fixes(stamps, t, x, y, theta, model, rng)
    return stamps, east, north, status


# Incremental use (a live simulator) -------------------------------------------------------

class _Stream:
    """
    Truth history and the index of the next reading; subclasses say what is due.

    ``model`` is a sensor model with a ``rate`` (Hz) and a ``latency`` (s).
    """

    def __init__(self, model, rng):
        self.model = model
        self._rng = rng
        self._t = np.empty(0)
        self._first = None
        self._next = 0

    def _append_times(self, times):
        times = np.atleast_1d(np.asarray(times, dtype=float))
        if times.ndim != 1 or not np.all(np.isfinite(times)):
            raise ValueError('times must be a finite 1-D array')
        joined = np.r_[self._t, times]
        if np.any(np.diff(joined) <= 0):
            raise ValueError('times must increase strictly across pushes')
        if self._first is None and times.size:
            self._first = float(times[0])
        return times

    def _due(self, ready_until):
        """Stamps of readings not yet returned whose truth ends at or before the given time."""
        if self._first is None or self._t.size < 2:
            return np.empty(0)
        last = min(ready_until, float(self._t[-1]))
        stamps = _stamps(self._first, last, self.model.rate, self._next)
        self._next += stamps.size
        return stamps

    def _trim(self):
        """
        Index of the oldest truth sample to keep.

        The next reading needs the truth from ``latency`` plus a period before its stamp;
        older truth is dropped but for one sample before that time.
        """
        m = self.model
        keep_from = self._first + self._next / m.rate - m.latency - 1.0 / m.rate
        k = int(np.searchsorted(self._t, keep_from)) - 1
        return max(k, 0)


class GyroStream(_Stream):
    """
    A :class:`GyroModel` fed with truth as it is simulated.

    Parameters
    ----------
    model : GyroModel
        The gyro.
    rng : numpy.random.Generator
        Source of noise and bias walk.

    Notes
    -----
    A reading stamped ``s`` is returned once the truth covers ``s - latency`` plus half a
    period, and never before the truth has reached ``s`` (no reading from the future).

    """

    def __init__(self, model: GyroModel, rng: np.random.Generator):
        super().__init__(model, rng)
        self._heading = np.empty(0)
        self._last_rate = 0.0
        self._bias = model.bias

    def push(self, times, yaw_rates):
        """
        Append truth: ``yaw_rates[k]`` is held from ``times[k]`` to the next time, rad/s.

        Returns
        -------
        stamps, z_rate : ndarray
            Readings that became due (possibly none).

        """
        times = self._append_times(times)
        w = np.atleast_1d(np.asarray(yaw_rates, dtype=float))
        if w.shape != times.shape or not np.all(np.isfinite(w)):
            raise ValueError('yaw_rates must be finite and match times')
        if times.size == 0:
            return np.empty(0), np.empty(0)
        if self._t.size:
            start = self._heading[-1] + self._last_rate * (times[0] - self._t[-1])
        else:
            start = 0.0
        heading = start + np.r_[0.0, np.cumsum(w[:-1] * np.diff(times))]
        self._t = np.r_[self._t, times]
        self._heading = np.r_[self._heading, heading]
        self._last_rate = float(w[-1])
        m = self.model
        stamps = self._due(float(self._t[-1]) + m.latency - 0.5 / m.rate)
        z, self._bias = _gyro_readings(stamps, self._t, self._heading, m, self._bias,
                                       self._rng)
        keep = self._trim()
        self._t, self._heading = self._t[keep:], self._heading[keep:]
        return stamps, z


class GnssStream(_Stream):
    """
    A :class:`GnssModel` fed with truth as it is simulated.

    Parameters
    ----------
    model : GnssModel
        The receiver.
    rng : numpy.random.Generator
        Source of noise and dropouts.

    """

    def __init__(self, model: GnssModel, rng: np.random.Generator):
        super().__init__(model, rng)
        self._pose = np.empty((0, 3))
        self._state = None

    def push(self, times, x, y, theta):
        """
        Append true poses (local plane, theta continuous) at ``times``.

        Returns
        -------
        stamps, east, north, status : ndarray
            Fixes that became due (possibly none), as :func:`gnss_samples`.

        """
        times = self._append_times(times)
        pose = np.column_stack(_pose_arrays(times, x, y, theta)) if times.size else None
        if pose is None:
            return np.empty(0), np.empty(0), np.empty(0), np.empty(0, dtype=np.int8)
        self._t = np.r_[self._t, times]
        self._pose = np.vstack([self._pose, pose])
        m = self.model
        stamps = self._due(float(self._t[-1]) + m.latency)
        east, north, status, state = _gnss_fixes(stamps, self._t, *self._pose.T, m,
                                                 self._rng, self._state)
        if stamps.size:
            self._state = state
        keep = self._trim()
        self._t, self._pose = self._t[keep:], self._pose[keep:]
        return stamps, east, north, status
