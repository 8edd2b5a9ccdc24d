"""
The models the identification fits, and where it searches: bounds and starting points.

The bounds are physical: tread ICRs lie outside the track centrelines (Martinez et al. 2005,
sec. 3: slip only moves them outwards), so ``0 < chi <= 1``; the encoder scales (Martinez
eqs. 20-21) stay near 1; the effective wheel-base factor (Fink & Stump sec. III-A, Table I)
lies in (0, 1]. The starting point is an ideal drive with its turning rate scaled to the
data's, a steering efficiency in the sense of Martinez eq. (16).
"""

from __future__ import annotations

import numpy as np

from .ddc import TunedDiffDrive
from .segments import Segments
from ..models import ConstantIcr, make_model, MotionModel

# Models the identification fits, in the order they are reported.
FIT_MODELS = ('effective_wheel_base', 'icr', 'icr_scales', 'general_slip', 'adaptive_icr')
BASELINES = ('ideal', 'tuned_ddc')
"""What a user has without this package: ideal drive, and diff_drive_controller tuned."""
COMPARE_MODELS = BASELINES + FIT_MODELS


def build_model(name: str, track_width: float, scales=(1.0, 1.0)) -> MotionModel:
    """
    Motion model by name; the ``icr`` model uses the fixed ``scales`` given.

    Parameters
    ----------
    name : str
        A name of :data:`..models.MODEL_NAMES`, or ``tuned_ddc`` (:class:`.ddc.TunedDiffDrive`).
    track_width : float
        m.
    scales : tuple of float
        Encoder scales of a model that does not fit them (``icr``).

    """
    if name == 'icr':
        return ConstantIcr(track_width, with_scales=False, scales=scales)
    if name == 'tuned_ddc':
        return TunedDiffDrive(track_width)
    return make_model(name, track_width)


def bounds(model: MotionModel):
    """
    Physical bounds for least squares: ``(lower, upper)`` arrays.

    Tread ICRs lie outside the track centrelines (Martinez sec. 3: slip only moves them
    outwards), which keeps ``0 < chi <= 1`` whatever the eccentricity; scales lie in
    [0.5, 2]; the effective wheel-base factor (Fink & Stump) in [0.05, 1], and DDC's
    ``wheel_separation_multiplier``, its inverse, in [1, 20]; the adaptive model's outward
    ICR terms ``p1..p4`` are >= 0. General slip is unbounded.
    """
    half = 0.5 * model.track_width
    lo, hi = [], []
    for name in model.param_names:
        lo_hi = {'alpha': (0.05, 1.0), 'y_left': (half, 20 * half), 'y_right': (-20 * half, -half),
                 'x': (-10 * half, 10 * half), 'scale_left': (0.5, 2.0),
                 'scale_right': (0.5, 2.0), 'p1': (0.0, np.inf), 'p2': (0.0, np.inf),
                 'p3': (0.0, np.inf), 'p4': (0.0, np.inf),
                 'wheel_separation_multiplier': (1.0, 20.0),
                 'left_wheel_radius_multiplier': (0.5, 2.0),
                 'right_wheel_radius_multiplier': (0.5, 2.0)}.get(name, (-np.inf, np.inf))
        lo.append(lo_hi[0])
        hi.append(lo_hi[1])
    return np.array(lo, float), np.array(hi, float)


def search_box(model: MotionModel):
    """
    Finite search box for a global method (differential evolution): ``(lower, upper)``.

    The physical :func:`bounds`, narrowed to what a tracked vehicle shows: ICRs within
    ``2 B`` of the centre and 1 B ahead or behind, scales within 20 %, general-slip
    coefficients within +-1, adaptive coefficients within 2 B.
    """
    lo, hi = bounds(model)
    b = model.track_width
    box = {'y_left': (0.5 * b, 2 * b), 'y_right': (-2 * b, -0.5 * b), 'x': (-b, b),
           'scale_left': (0.8, 1.2), 'scale_right': (0.8, 1.2),
           'p1': (0.0, 2 * b), 'p2': (0.0, 2 * b), 'p3': (0.0, 2 * b), 'p4': (0.0, 2 * b),
           'p5': (-2 * b, 2 * b), 'p6': (-2 * b, 2 * b),
           'wheel_separation_multiplier': (1.0, 4.0), 'left_wheel_radius_multiplier': (0.8, 1.2),
           'right_wheel_radius_multiplier': (0.8, 1.2)}
    for i, name in enumerate(model.param_names):
        if name in box:
            lo[i], hi[i] = box[name]
        elif not np.isfinite(lo[i]) or not np.isfinite(hi[i]):
            lo[i], hi[i] = -1.0, 1.0
    return lo, hi


def steering_efficiency_guess(segments: Segments, track_width: float) -> float:
    """
    Least-squares ratio of measured to ideal heading change, clipped to [0.2, 1].

    The data's steering efficiency in the sense of Martinez eq. (16), over every segment
    rather than spins only: a starting point for the fit.
    """
    ideal = segments.ideal_turn / track_width
    denom = float(np.dot(ideal, ideal))
    if denom <= 0.0:
        return 1.0
    chi = float(np.dot(segments.truth[:, 2], ideal)) / denom
    return float(np.clip(chi, 0.2, 1.0))


def initial_guess(model: MotionModel, segments: Segments) -> np.ndarray:
    """Start of the fit: ideal drive, with the turning rate scaled to the data's."""
    p = model.initial().astype(float)
    chi = steering_efficiency_guess(segments, model.track_width)
    names = model.param_names
    if 'alpha' in names:
        p[names.index('alpha')] = chi
    if 'wheel_separation_multiplier' in names:
        p[names.index('wheel_separation_multiplier')] = 1.0 / chi
    if 'y_left' in names:
        half = 0.5 * model.track_width / chi
        p[names.index('y_left')] = half
        p[names.index('y_right')] = -half
    if 'p2' in names and len(segments.dt):
        # Adaptive ICRs: the curvature terms put them where the efficiency guess does, at the
        # median curvature of the turning steps.
        _, curv = model.features(segments.d_left / segments.dt, segments.d_right / segments.dt)
        turning = curv[curv > 1e-3]
        if len(turning):
            outward = 0.5 * model.track_width * (1.0 / chi - 1.0) / float(np.median(turning))
            p[names.index('p2')] = p[names.index('p4')] = outward
    return p
