"""
Sensor models of the simulator: a yaw-rate gyro and a GNSS receiver, vectorised.

Batch functions (:func:`gyro_samples`, :func:`gnss_samples`) and incremental streams with the same
statistics take the simulated truth and a ``numpy.random.Generator``. Conventions (truth holding,
latency, the integrating gyro, Gauss-Markov GNSS): docs/simulator.md, "Sensor models".
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

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
    A z-axis rate gyro; all SI (Hz, rad/s, rad/s/sqrt(s) for ``bias_walk``, s).

    A reading stamped ``s`` shows the truth at ``s - latency``; ``saturation`` clips (inf: none).
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
        # tracked_simulator's gyro_* parameters, simulate_bag's --imu-scale).
        require_numbers(self, positive=('scale',))


@dataclass(frozen=True, slots=True)
class GnssModel:
    """
    A GNSS receiver: horizontal position of its antenna (``antenna_x, antenna_y``: m).

     ``noise_std`` per axis, m; ``correlation_time`` s (0: white); ``dropout`` a probability;
    ``status`` NavSatStatus of a good fix.
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
    Gyro readings ``(stamps, z_rate)`` of a simulated run, at ``model.rate``.

    ``yaw_rate_true`` (rad/s, length N or N - 1) is held over each step of ``times_true`` (s,
    increasing). Stamps are ``times_true[0] + k / model.rate``; ``z_rate`` is REP-103 (CCW +).
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
    from scipy.signal import lfilter   # lazily: 0.4 s to import
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
    GNSS fixes ``(stamps, east, north, status)`` of a simulated run, in the local plane.

    ``x, y, theta`` are base_link's true pose (east, north: m; theta continuous, rad). East and
    north are NaN where ``status`` is ``STATUS_NO_FIX``; :func:`enu_to_geodetic` converts.
    """
    t = _truth_times(times_true)
    x, y, theta = _pose_arrays(t, x, y, theta)
    stamps = _stamps(t[0], t[-1], model.rate)
    east, north, status, _ = _gnss_fixes(stamps, t, x, y, theta, model, rng)
    return stamps, east, north, status


# Incremental use (a live simulator) -------------------------------------------------------

class _Stream:
    """Truth history and the index of the next reading; subclasses say what is due."""

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
        """Index of the oldest truth sample the next reading may need."""
        m = self.model
        keep_from = self._first + self._next / m.rate - m.latency - 1.0 / m.rate
        k = int(np.searchsorted(self._t, keep_from)) - 1
        return max(k, 0)


class GyroStream(_Stream):
    """A :class:`GyroModel` fed with truth as it is simulated (no reading from the future)."""

    def __init__(self, model: GyroModel, rng: np.random.Generator):
        super().__init__(model, rng)
        self._heading = np.empty(0)
        self._last_rate = 0.0
        self._bias = model.bias

    def push(self, times, yaw_rates):
        """Append truth (``yaw_rates[k]`` held from ``times[k]``); return readings now due."""
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
    """A :class:`GnssModel` fed with truth as it is simulated."""

    def __init__(self, model: GnssModel, rng: np.random.Generator):
        super().__init__(model, rng)
        self._pose = np.empty((0, 3))
        self._state = None

    def push(self, times, x, y, theta):
        """Append true poses at ``times``; return fixes now due, as :func:`gnss_samples`."""
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
