"""
The models the identification fits, and where it searches: bounds and starting points.

Reads each model's declared bounds, search box and start. The bounds are physical: slip only moves
tread ICRs outwards (Martinez et al. 2005, sec. 3), so ``0 < chi <= 1``; scales (eqs. 20-21) stay
near 1; the effective wheel-base factor (Fink & Stump Table I) is in (0, 1].
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
    """Motion model by name (``tuned_ddc`` too); one without scale parameters uses ``scales``."""
    return model_class(name).build(track_width, scales)


def bounds(model: MotionModel):
    """Physical bounds ``(lower, upper)`` for least squares: declared, else none."""
    b = model.track_width
    lo, hi = [], []
    for name in model.param_names:
        param = model.parameter(name)
        scale = b if param.per_track_width else 1.0
        lo.append(param.bounds[0] * scale)
        hi.append(param.bounds[1] * scale)
    return np.array(lo, float), np.array(hi, float)


def search_box(model: MotionModel):
    """Finite box ``(lower, upper)`` for a global search: declared, finite bounds, or +-1."""
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
    """Least-squares ratio of measured to ideal turning (Martinez eq. 16), clipped to [0.2, 1]."""
    ideal = segments.ideal_turn / track_width
    denom = float(np.dot(ideal, ideal))
    if denom <= 0.0:
        return 1.0
    chi = float(np.dot(segments.truth[:, 2], ideal)) / denom
    return float(np.clip(chi, 0.2, 1.0))


def initial_guess(model: MotionModel, segments: Segments) -> np.ndarray:
    """Start of the fit: the model's :meth:`~..models.MotionModel.guess` at the data's chi."""
    return model.guess(steering_efficiency_guess(segments, model.track_width), segments)
