"""
Identification without a ground-truth pose: a gyro for heading, GNSS or a straight for distance.

Most tracked and skid-steer robots carry track encoders and an IMU, few a motion-capture or
lidar pose. A gyro sees the heading, exactly what the ICR spread (chi) and a robot that
veers (the right / left scale ratio) change; it sees nothing of how far the robot went
(the distance scale), where the ICRs lie along it (``icr.x``) or sideways (the offset of the
ICR pair). A position reference (GNSS, a pose) or one straight drive of measured length
gives the distance scale, and ``icr.x`` where its noise allows.

The one function a caller needs
-------------------------------
``fit_from_reference(enc_t, left, right, *, track_width, gyro_t=None, gyro_rate=None,
gyro_yaw=None, pose=None, positions=None, straight_distance=None, base=None,
imu_delay='auto', pose_delay='auto', segment_length=1.0, position_window=None, hold=(),
gnss_antenna=(0, 0)) -> ReferenceFit``

Plain arrays in (one recording; :func:`fit_recordings` takes several
:class:`~tracked_kinematics.core.recording.Recording`): encoder times (s) and cumulative
nominal track travel (m); gyro stamps (s) and yaw rates (rad/s, REP-103), or yaw angles from
an orientation; an optional pose ``(t, x, y, yaw)`` and optional positions ``(t, x, y)`` in a
local plane (GNSS, :mod:`tracked_kinematics.core.geodesy`). Out: :class:`ReferenceFit`, with
``.icr`` (the :class:`~tracked_kinematics.core.kinematics.IcrParams` to write), ``.determined``
and ``.held`` (lists of ``chi``, ``scale_ratio``, ``distance_scale``, ``icr.x``, ``icr_offset``),
``.reference`` (``'imu'``, ``'imu+gnss'``, ...) and ``.report`` (a JSON-ready dict).
Errors: :class:`~tracked_kinematics.core.errors.SensorDataError` for unusable sensor data
(a gyro all zero or NaN, saturated), ``ExcitationError`` for data that cannot determine
what is asked (too little turning; a "straight" that turns; positions too noisy for the
distance), ``FitError`` for an invalid result; one line each. A node calls, for example::

    fit = fit_from_reference(enc_t, left, right, track_width=0.42, gyro_t=imu_t,
                             gyro_rate=imu_wz, base=current_icr)
    fit.icr, fit.held, fit.report['imu_delay']['delay']

The model
---------
Constant tread ICRs (Martinez et al. 2005, eqs. 7-9 with the scales of eqs. 20-21): over
any interval the heading change is exactly linear in the nominal travel of the tracks,

    dpsi = (s_r D_r - s_l D_l) / W = u (D_r - D_l) + v (D_r + D_l),

with the spread ``W = y_left - y_right``, the *turn gain* ``u = s / W`` (``s`` the distance
scale, ``(s_l + s_r) / 2``) and the *veer* ``v = (s_r - s_l) / (2 W)``. Heading alone gives
``u`` and ``v``: chi ``= track_width u / s`` at the held distance scale, and the scale ratio
``s_r / s_l = (u + v) / (u - v)``. A gyro reads ``dpsi / dt + b`` with a bias ``b``: over
segments of ``segment_length`` s, ``(u, v, b_1 .. b_R)`` (one bias per recording) are
a linear least-squares problem, solved with Huber weights (iterated, :data:`HUBER_K`
robust standard deviations); stationary segments stay in (they time the bias best). The
noise is taken from the data (the robust spread of the residuals per source), so a gyro
and a pose heading are weighted by it when both are given. Veer needs straight driving and
turns; without enough of both (standard error of the ratio above
:data:`RATIO_STD_LIMIT`) the ratio is held.

With positions (GNSS or a pose), the body step over each short interval is
``(s m + c dpsi, -x dpsi)`` with ``m = (D_l + rho D_r) / (1 + rho)``, ``rho`` the scale
ratio of the heading fit, ``c`` the ICR offset ``(y_left + y_right) / 2`` and ``x = icr.x``
(the forward kinematics of docs/model.md), rotated by the gyro heading. Positions are
compared in windows of ``position_window`` s, each centred on its mean (the dead reckoning
drifts; a window does not care where it starts), after a rotation ``theta_R + delta_R t``
per recording and source (the gyro's frame is not the reference's, and a residual bias
turns it slowly). ``s`` is fitted, ``x`` (and ``c`` from a pose) when their standard errors
are below :data:`X_STD_LIMIT`; else they are held. ``W = s / u`` then follows.

``straight_distance`` (m): the recordings are one straight drive of that measured length.
The distance scale is that length over the chord the encoders give; a drive that turns by
more than :data:`MAX_STRAIGHT_TURN` is refused.

Delay: the gyro's stamps against the encoders are estimated by :func:`..delay.estimate_delay`
(heading channel) on the integrated gyro, exactly as the pose delay is, and removed;
``imu_delay`` > 0 means the gyro is stamped late (on the Warthog logs of ../shared/realdata
the encoders trail the gyro by about 0.17 s: ``imu_delay`` about -0.17 s).

The modules, one job each
-------------------------
:mod:`.recordings` (the data, the result, the checks of the sensor data), :mod:`.delays`
(step 2 of :func:`fit_recordings`), :mod:`.headings` (the heading references cut into
segments; :func:`heading_reference`), :mod:`.heading_fit` (the heading: ``u``, ``v``, the
biases), :mod:`.positions` (the distance: positions or a straight) and :mod:`.calibration`
(:func:`fit_recordings`, step by step, and :func:`fit_from_reference`).
"""

from .calibration import fit_from_reference, fit_recordings
from .heading_fit import CHI_REL_STD_LIMIT, HUBER_K, MIN_TURN, RATIO_STD_LIMIT
from .headings import heading_reference, MAX_STRAIGHT_TURN, MIN_MOVING_SEGMENTS
from .positions import DISTANCE_STD_LIMIT, POSITION_WINDOW, X_STD_LIMIT
from .recordings import (
    check_gyro, check_saturation, QUANTITIES, ReferenceFit, SATURATION_SHARE)

__all__ = [
    'CHI_REL_STD_LIMIT', 'DISTANCE_STD_LIMIT', 'HUBER_K', 'MAX_STRAIGHT_TURN',
    'MIN_MOVING_SEGMENTS', 'MIN_TURN', 'POSITION_WINDOW', 'QUANTITIES', 'RATIO_STD_LIMIT',
    'ReferenceFit', 'SATURATION_SHARE', 'X_STD_LIMIT', 'check_gyro',
    'check_saturation', 'fit_from_reference', 'fit_recordings', 'heading_reference',
]
