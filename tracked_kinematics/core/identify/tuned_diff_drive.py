"""
The baseline a tracked-robot user already has: ros2_controllers' diff_drive_controller, tuned.

DDC's odometry ``v = (m_l D_l + m_r D_r) / 2``, ``w = (m_r D_r - m_l D_l) / (m_s B)`` is the
constant-ICR model (Martinez eqs. 7-9, 20-21) with symmetric ICRs at ``+-m_s B / 2``. See
docs/migrating-from-diff_drive_controller.md.
"""

from __future__ import annotations

import numpy as np

from ..kinematics import IcrParams
from ..models import MotionModel, Parameter, register_model

DDC_PARAMS = ('wheel_separation_multiplier', 'left_wheel_radius_multiplier',
              'right_wheel_radius_multiplier')
"""The diff_drive_controller parameters :class:`TunedDiffDrive` fits, by their DDC names."""


@register_model
class TunedDiffDrive(MotionModel):
    """diff_drive_controller's odometry; ``p = (m_s, m_l, m_r)`` are its multipliers."""

    name = 'tuned_ddc'
    # The separation multiplier is the inverse of an effective wheel-base factor (0.05-1).
    parameters = (
        Parameter(DDC_PARAMS[0], excited_by='turning', bounds=(1.0, 20.0), box=(1.0, 4.0),
                  std_checked=True),
        *(Parameter(name, excited_by='straight', bounds=(0.5, 2.0), box=(0.8, 1.2),
                    std_checked=True) for name in DDC_PARAMS[1:]))
    linear = True
    constant_icr = True
    baseline = True

    def initial(self):
        return np.ones(3)

    def guess(self, chi, segments):
        p = self.initial().astype(float)
        p[0] = 1.0 / chi
        return p

    def twist_and_jacobian(self, p, v_left, v_right):
        m_s, m_l, m_r = (float(v) for v in np.asarray(p, float))
        v_left = np.atleast_1d(np.asarray(v_left, float))
        v_right = np.atleast_1d(np.asarray(v_right, float))
        separation = m_s * self.track_width
        left, right = m_l * v_left, m_r * v_right
        v_x = 0.5 * (left + right)
        w = (right - left) / separation
        zero = np.zeros_like(v_x)
        twist = np.stack([v_x, zero, w], axis=-1)
        jac = np.zeros(twist.shape + (3,))
        jac[..., 0, 1] = 0.5 * v_left
        jac[..., 0, 2] = 0.5 * v_right
        jac[..., 2, 0] = -w / m_s
        jac[..., 2, 1] = -v_left / separation
        jac[..., 2, 2] = v_right / separation
        return twist, jac

    def as_icr(self, p):
        m_s, m_l, m_r = (float(v) for v in np.asarray(p, float))
        half = 0.5 * m_s * self.track_width
        return IcrParams(self.track_width, half, -half, 0.0, m_l, m_r)


def ddc_parameters(p, track_width: float, wheel_radius: float) -> dict[str, float]:
    """
    Return the diff_drive_controller parameters, by DDC's names, of a :class:`TunedDiffDrive` fit.

    ``track_width`` and ``wheel_radius`` (m) are the nominal values the multipliers apply to.
    """
    m_s, m_l, m_r = (float(v) for v in np.asarray(p, float))
    return {'wheel_separation': float(track_width), 'wheel_separation_multiplier': m_s,
            'wheel_radius': float(wheel_radius), 'left_wheel_radius_multiplier': m_l,
            'right_wheel_radius_multiplier': m_r}
