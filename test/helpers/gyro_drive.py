"""A drive with a gyro of known bias, scale, offset in time and slip, for the gyro tests."""

import numpy as np


def gyro_drive(icr, seed=0, seconds=14.0, still=3.5, rate=50.0, gyro_rate=400.0, bias=0.02,
               scale=1.02, delay=0.05, slip=0.8, noise=0.002):
    """
    Return ``t, left, right, gyro_t, gyro_rate``: a standstill, then arcs and spins.

    ``left``, ``right``: cumulative nominal travel (m) at the encoder times ``t`` (s). The
    ground turns the robot ``slip`` times what the model ``icr`` says; the gyro reads
    ``scale`` times the true rate plus ``bias`` and white noise of std ``noise`` (rad/s), and
    is stamped ``delay`` s late.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * rate) + 1) / rate
    moving = t >= still
    v = np.where(moving, 0.3 * np.sin(0.7 * t) + 0.1, 0.0)
    turn = np.where(moving, 0.25 * np.sin(0.45 * t + 1.0), 0.0)
    v_left, v_right = v - turn, v + turn
    left = np.concatenate([[0.0], np.cumsum(v_left[1:]) / rate])
    right = np.concatenate([[0.0], np.cumsum(v_right[1:]) / rate])
    tg = np.arange(int(seconds * gyro_rate) + 1) / gyro_rate
    w_model = np.interp(tg, t, (icr.scale_right * v_right - icr.scale_left * v_left)
                        / (icr.y_left - icr.y_right))
    reading = scale * slip * w_model + bias + noise * rng.standard_normal(len(tg))
    return t, left, right, tg + delay, reading


def true_heading(icr, t, left, right, slip=0.8):
    """Return the true heading (rad) at the encoder times: slip times the model's."""
    d_left, d_right = np.diff(left), np.diff(right)
    dpsi = (icr.scale_right * d_right - icr.scale_left * d_left) / (icr.y_left - icr.y_right)
    return np.concatenate([[0.0], np.cumsum(slip * dpsi)])
