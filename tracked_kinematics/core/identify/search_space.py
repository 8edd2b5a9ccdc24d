"""
The models the identification fits, and where it searches: bounds and starting points.

Each model declares its parameters' bounds and search box (:class:`..models.Parameter`) and
its starting point (:meth:`..models.MotionModel.guess`); this module reads them. The bounds
are physical: tread ICRs lie outside the track centrelines (Martinez et al. 2005, sec. 3:
slip only moves them outwards), so ``0 < chi <= 1``; the encoder scales (Martinez eqs.
20-21) stay near 1; the effective wheel-base factor (Fink & Stump sec. III-A, Table I) lies
in (0, 1]. The starting point is the model as a drive of the data's steering efficiency in
the sense of Martinez eq. (16).
"""

from __future__ import annotations

import numpy as np

from .segments import Segments
from .tuned_diff_drive import TunedDiffDrive  # noqa: F401 (registers tuned_ddc)
from ..models import model_class, model_names, MotionModel


def fit_models() -> tuple[str, ...]:
    """Return the registered models the identification fits, in the order they are reported."""
    return tuple(n for n in model_names(aliases=False) if not model_class(n).baseline)


def baselines() -> tuple[str, ...]:
    """Return the registered baselines: what a user has without this package."""
    return tuple(n for n in model_names(aliases=False) if model_class(n).baseline)


# Models the identification fits, in the order they are reported.
FIT_MODELS = fit_models()
BASELINES = baselines()
"""What a user has without this package: ideal drive, and diff_drive_controller tuned."""
COMPARE_MODELS = BASELINES + FIT_MODELS


def build_model(name: str, track_width: float, scales=(1.0, 1.0)) -> MotionModel:
    """
    Motion model by name; a model without scale parameters uses the fixed ``scales`` given.

    Parameters
    ----------
    name : str
        A registered name (:func:`..models.model_names`: ``tuned_ddc`` too).
    track_width : float
        m.
    scales : tuple of float
        Encoder scales of a model that does not fit them (``icr``).

    """
    return model_class(name).build(track_width, scales)


def bounds(model: MotionModel):
    """
    Physical bounds for least squares: ``(lower, upper)`` arrays.

    Each parameter's declared :attr:`..models.Parameter.bounds` (in track widths where it
    says so); undeclared ones are unbounded.
    """
    b = model.track_width
    lo, hi = [], []
    for name in model.param_names:
        param = model.parameter(name)
        scale = b if param.per_track_width else 1.0
        lo.append(param.bounds[0] * scale)
        hi.append(param.bounds[1] * scale)
    return np.array(lo, float), np.array(hi, float)


def search_box(model: MotionModel):
    """
    Finite search box for a global method (differential evolution): ``(lower, upper)``.

    Each parameter's declared :attr:`..models.Parameter.box`; else its :func:`bounds`
    where finite, else +-1.
    """
    lo, hi = bounds(model)
    b = model.track_width
    for i, name in enumerate(model.param_names):
        param = model.parameter(name)
        if param.box is not None:
            scale = b if param.per_track_width else 1.0
            lo[i], hi[i] = param.box[0] * scale, param.box[1] * scale
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
    """Start of the fit: the model's :meth:`~..models.MotionModel.guess` at the data's chi."""
    return model.guess(steering_efficiency_guess(segments, model.track_width), segments)
