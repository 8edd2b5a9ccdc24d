"""
Odometry as a small state machine: nominal track travel in, pose, twist and covariance out.

Scales (Martinez eqs. 20-21), tread ICRs (eqs. 7-9), the exact arc and the covariance, in plain
floats (microseconds a step). A step that would make anything non-finite is refused whole, so the
state never freezes. See docs/nodes/odometry_node.md.
"""

from __future__ import annotations

import math

import numpy as np

from .covariance import (
    arc_step, body_jacobian, full_matrix, propagate, saturate, TrackNoise, travel_jacobian,
    twist_covariance, TWIST_TIME, twist_variances)
from .kinematics import IcrParams
from .noise_model import NoiseModel, published_covariance, turn_slip, turn_slip_step

_ZERO_COVARIANCE = (0.0,) * 6

# Largest travel of a track in one step, m: beyond it a step is refused whatever its
# duration (a plausibility gate upstream refuses far less; this bound keeps the state
# finite and meaningful for any caller).
MAX_STEP_TRAVEL = 1e9

# Beyond this |theta| (rad, 160,000 turns) the heading is brought back into [-pi, pi]: a
# continuous heading that grew without bound would lose the resolution to turn at all.
_HEADING_WRAP = 1e6


class Published:
    """
    What odometry_node publishes from either odometry: one interface, one covariance.

    :class:`Odometry` and :class:`.gyro.GyroOdometry` are stepped with :meth:`step`, fed gyro
    samples with ``imu`` (the former refuses them), published with :meth:`publish` and reset
    with :meth:`reset`; the node and evaluate_model ``--fuse-imu`` call the same methods, so
    the covariance scored is the one published.
    """

    timing: NoiseModel | None = None
    gyro_timing: NoiseModel | None = None
    source = 'encoders'
    reason = 'imu_topic is empty'
    level = 'ok'
    _last_twist = (0.0, 0.0, 0.0)

    def set_timing(self, model: NoiseModel | None, gyro: NoiseModel | None = None) -> None:
        """
        Publish with the ``timing``, ``scale`` and ``drift`` terms of ``model`` (none: None, 0).

        ``gyro``: those published while the heading is the gyro's (default ``model``'s).
        """
        self.timing = model if model is not None and model.beside_the_steps else None
        gyro = model if gyro is None else gyro
        self.gyro_timing = gyro if gyro is not None and gyro.beside_the_steps else None

    def timing_now(self) -> NoiseModel | None:
        """Return the terms published beside the steps now (the encoders': ``timing``)."""
        return self.timing

    def reset(self) -> None:
        """Return the pose to zero with zero covariance; the time error at the start stays."""
        self.pose = (0.0, 0.0, 0.0)
        self.covariance_upper = _ZERO_COVARIANCE
        self.steps = 0
        # A robot reset while it moves has its time error at the start too: the rates then
        # (the last twist published), in the new frame (heading 0).
        self._start_twist = self._last_twist

    def publish(self, covariance: bool = True):
        """
        Return what is published now: ``(pose, pose covariance, twist, twist covariance)``.

        The twist is the mean since the last call (``take_twist``); the pose covariance the
        propagated one plus the time error at both ends of the interval since the last reset
        (:func:`.noise_model.published_covariance`). ``covariance`` False: the twist is
        taken as for a message, but neither covariance is computed (None), for a replay
        that scores only some of its samples (:func:`.gyro.replay`'s ``published_at``).
        """
        twist, twist_covariance = self.take_twist(covariance)
        if all(map(math.isfinite, twist)):
            self._last_twist = twist
        if not covariance:
            return self.pose, None, twist, None
        covariance = published_covariance(self.covariance_upper, self.pose, twist,
                                          self._start_twist, self.timing_now())
        return self.pose, covariance, twist, twist_covariance

    def beside_the_steps(self, twist, model: NoiseModel):
        """
        Return what ``model``'s timing, scale and drift would add to the covariance published now.

        ``twist``: the one :meth:`publish` just returned. The published covariance is affine in
        these terms, so a fit of theirs replays the steps once (:func:`.gyro.replay`).
        """
        return published_covariance(_ZERO_COVARIANCE, self.pose, twist, self._start_twist, model)

    @staticmethod
    def _wrapped(theta: float) -> float:
        """Bring a heading that grew beyond :data:`_HEADING_WRAP` back into [-pi, pi]."""
        return math.remainder(theta, 2.0 * math.pi) if abs(theta) > _HEADING_WRAP else theta


class Odometry(Published):
    """
    Dead reckoning of a tracked vehicle through its tread ICRs.

    ``pose`` is ``(x, y, theta)`` (m, m, rad; theta continuous); ``covariance_upper`` the upper
    triangle ``(xx, xy, xt, yy, yt, tt)``; ``steps`` those since the start or :meth:`reset`.

    ``noise`` is the track random walk of each track; ``terms``, optional, adds the ``turn``
    and ``slip`` terms of a :class:`.noise_model.NoiseModel` (its ``track`` and ``floor`` are
    ``noise``'s; its ``timing`` is the publisher's: :func:`.noise_model.timing_covariance`).
    Without them (or with both 0) the covariance is the track random walk alone.
    """

    def __init__(self, icr: IcrParams, noise: TrackNoise | None = None,
                 terms: NoiseModel | None = None):
        self.terms = None
        self.set_model(icr, noise if noise is not None else TrackNoise(), terms)
        self.reset()

    def imu(self, t: float, wz: float) -> bool:
        """Refuse a gyro sample: this odometry has none (False)."""
        return False

    def step(self, t: float, d_left: float, d_right: float, dt: float) -> bool:
        """
        Integrate one step ending at ``t`` (s): :meth:`update`, as the gyro-aided odometry's.

        ``t`` is not used here: the tracks alone need no clock.
        """
        return self.update(d_left, d_right, dt)

    def set_model(self, icr: IcrParams, noise: TrackNoise | None = None,
                  terms: NoiseModel | None = None) -> None:
        """Use another kinematic model (and noise) from the next step on; keep the pose."""
        self.icr = icr
        if noise is not None:
            self.noise = noise
        if terms is not None:
            self.terms = terms if (terms.turn > 0.0 or terms.slip > 0.0) else None
        self._body = body_jacobian(icr)

    def reset(self) -> None:
        """Return the pose to zero with zero covariance, and restart the twist window."""
        super().reset()
        self._clear_window()

    def _clear_window(self) -> None:
        # Sums over the steps since the twist was last taken: nominal travel of each
        # track, distance each travelled (sum of |travel|), samples, duration.
        self._window = [0.0, 0.0, 0.0, 0.0, 0, 0.0]

    @property
    def covariance(self) -> np.ndarray:
        """Covariance of ``(x, y, theta)``, 3 x 3, symmetric positive semi-definite."""
        return full_matrix(self.covariance_upper)

    def update(self, d_left: float, d_right: float, dt: float) -> bool:
        """
        Integrate nominal travel ``d_left``, ``d_right`` (m) over ``dt`` s; False if refused.

        Refused, with the state unchanged: non-finite input, speed or result, ``dt <= 0``, or a
        track travelling more than :data:`MAX_STEP_TRAVEL`.
        """
        if not (math.isfinite(d_left) and math.isfinite(d_right) and math.isfinite(dt)
                and dt > 0.0 and abs(d_left) <= MAX_STEP_TRAVEL
                and abs(d_right) <= MAX_STEP_TRAVEL
                and math.isfinite(d_left / dt) and math.isfinite(d_right / dt)):
            return False
        (b0l, b0r), (b1l, b1r), (b2l, b2r) = self._body
        x, y, theta = self.pose
        dx = b0l * d_left + b0r * d_right
        dy = b1l * d_left + b1r * d_right
        dtheta = b2l * d_left + b2r * d_right
        if not (math.isfinite(dx) and math.isfinite(dy) and math.isfinite(dtheta)):
            return False
        delta_x, delta_y, m = arc_step(theta, dx, dy, dtheta)
        var_left, var_right = self.noise.travel_variances(d_left, d_right)
        covariance = propagate(self.covariance_upper, delta_x, delta_y,
                               travel_jacobian(m, self._body), var_left, var_right)
        terms = self.terms
        if terms is not None:
            covariance = turn_slip_step(
                covariance, *turn_slip(terms, self.icr.track_width, dx, dtheta), m)
        covariance = saturate(covariance)
        pose = (x + delta_x, y + delta_y, self._wrapped(theta + dtheta))
        if not (math.isfinite(pose[0]) and math.isfinite(pose[1])
                and math.isfinite(covariance[0]) and math.isfinite(covariance[3])):
            return False
        self.pose = pose
        self.covariance_upper = covariance
        self.steps += 1
        window = self._window
        window[0] += d_left
        window[1] += d_right
        window[2] += abs(d_left)
        window[3] += abs(d_right)
        window[4] += 1
        window[5] += dt
        return True

    def take_twist(self, covariance: bool = True):
        """
        Mean body twist (m/s, m/s, rad/s) since the last call, and its covariance's upper triangle.

        The twist of the summed travel over the window's duration; the covariance is that of
        :func:`.covariance.twist_variances` (rate-independent) plus the floor on ``v_y``
        (``covariance`` False: None). The window then restarts.
        """
        d_left, d_right, abs_left, abs_right, samples, duration = self._window
        self._clear_window()
        if samples == 0:
            duration = 1.0
        (b0l, b0r), (b1l, b1r), (b2l, b2r) = self._body
        v_left = d_left / duration
        v_right = d_right / duration
        twist = (b0l * v_left + b0r * v_right, b1l * v_left + b1r * v_right,
                 b2l * v_left + b2r * v_right)
        if not covariance:
            return twist, None
        var_left, var_right = twist_variances(self.noise, abs_left / duration,
                                              abs_right / duration)
        xx, xy, xt, yy, yt, tt = twist_covariance(self._body, var_left, var_right, TWIST_TIME)
        if self.terms is not None:
            # The turn and slip terms of the mean twist over TWIST_TIME: S(v T) / T^2.
            position, heading = turn_slip(self.terms, self.icr.track_width,
                                          twist[0] * TWIST_TIME, twist[2] * TWIST_TIME)
            scale = 1.0 / (TWIST_TIME * TWIST_TIME)
            xx += position * scale
            yy += position * scale
            tt += heading * scale
        # With icr.x = 0 the model says v_y = 0 exactly; no model is exact, and a filter
        # should never be handed a zero variance: v_y is known to the floor's precision.
        return twist, (xx, xy, xt, yy + self.noise.floor / (TWIST_TIME * TWIST_TIME), yt, tt)
