"""
Fit a motion model to segments: robust, bounded least squares of Martinez eq. (17).

Soft-L1 loss, bounds from :func:`.search_space.bounds`, a check from the standard errors that the
data identify each parameter; differential evolution stands in for Martinez's genetic algorithm.
See docs/tools/identify_icr.md, "How it fits".
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
import time

import numpy as np

from .excitation import ros_names
from .problem import DEFAULT_HEADING_WEIGHT, LOSSES, robust_cost, SegmentProblem
from .search_space import bounds, initial_guess, search_box
from .segments import Segments
from ..errors import ExcitationError, FitError
from ..kinematics import IcrParams
from ..models import MotionModel

METHODS = ('lsq', 'de')


def _mad_sigma(values) -> float:
    values = np.asarray(values, dtype=float)
    if len(values) == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(values - np.median(values))))


def auto_heading_weight(residuals, lo: float = 0.25, hi: float = 4.0) -> float:
    """
    Heading weight ``lambda`` (m/rad) that puts position and heading residuals on one noise scale.

    Eq. (17) then weighs each residual by its own noise: ``sigma_position / sigma_heading`` (median
    absolute deviations of residuals at ``lambda = 1``), clipped to [``lo``, ``hi``]; Martinez's
    unweighted sum is ``lambda = 1``.
    """
    r = np.asarray(residuals, dtype=float).reshape(-1, 3)
    sigma_pos = _mad_sigma(r[:, :2].ravel())
    sigma_head = _mad_sigma(r[:, 2])
    if sigma_pos <= 0.0 or sigma_head <= 0.0:
        return 1.0
    return float(np.clip(sigma_pos / sigma_head, lo, hi))


@dataclass
class FitResult:
    """
    A fitted model ``p`` and how well it fits.

    Attributes
    ----------
    heading_weight, f_scale : float
        ``lambda`` (m/rad) and the robust loss scale used.
    rms_position, rms_heading : float
        RMS of the inlier position (m) and heading (rad) residuals.
    segments, inliers : int
        Segments fitted, and those whose residuals are all within 3 ``f_scale``.
    std, sigma : ndarray, float
        Standard errors (inf: not identified) and the residual noise per degree of freedom
        they are scaled by.

    """

    model: MotionModel
    p: np.ndarray
    method: str = 'lsq'
    loss: str = 'soft_l1'
    heading_weight: float = DEFAULT_HEADING_WEIGHT
    f_scale: float = 1.0
    cost: float = 0.0
    rms_position: float = 0.0
    rms_heading: float = 0.0
    segments: int = 0
    inliers: int = 0
    std: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sigma: float = 0.0
    nfev: int = 0
    seconds: float = 0.0
    message: str = ''

    @property
    def params(self) -> dict[str, float]:
        """Parameters by name."""
        return dict(zip(self.model.param_names, map(float, self.p)))

    @property
    def icr(self) -> IcrParams | None:
        """Return the constant-ICR model equal to the fitted one, or None if there is none."""
        return self.model.as_icr(self.p)


def _standard_errors(jac, residuals, inlier_rows, with_sigma=False):
    """Compute standard errors from the Jacobian and inlier residuals (inf: unidentified)."""
    n_params = jac.shape[1]
    jac = jac[inlier_rows]
    variance = float(np.sum(residuals[inlier_rows] ** 2)) / max(len(jac) - n_params, 1)
    norms = np.linalg.norm(jac, axis=0)
    std = np.full(n_params, np.inf)
    ok = norms > 0
    while np.any(ok):
        _, sv, vt = np.linalg.svd(jac[:, ok] / norms[ok], full_matrices=False)
        if sv[-1] > 1e-9 * sv[0]:
            cov = (vt.T / sv ** 2) @ vt
            std[ok] = np.sqrt(np.maximum(np.diag(cov) * variance, 0.0)) / norms[ok]
            break
        # Rank deficient: the parameters along the null direction are not identified.
        ok[np.flatnonzero(ok)[np.abs(vt[-1]) > 0.1]] = False
    return (std, math.sqrt(variance)) if with_sigma else std


# Largest standard error that still counts as identified, per parameter kind.
STD_LIMITS = {'icr': 0.1, 'scale': 0.02}   # icr: x track width; scale: absolute
REFERENCE_RESIDUAL = 0.01
"""
Residual noise of good ground truth per segment, m (heading through the heading weight).

About 10 mm and 0.6 deg per 1-s segment: motion capture, RTK, a lidar ICP on a structured
site. A parameter whose standard error is over its limit, but would be within it with
residuals this small, is determined by the driving and blurred by the ground truth
(:class:`Uncertain` ``cause == 'noise'``).
"""


class UncertainError(ExcitationError):
    """A parameter is determined by the data but its standard error is beyond its limit."""


@dataclass(frozen=True)
class Uncertain:
    """
    A parameter the data determine, with a standard error beyond its limit.

    ``cause`` is ``'noise'`` (it would be within the limit with residuals of
    :data:`REFERENCE_RESIDUAL`, its ``reference_std``) or ``'excitation'`` (too little of the
    driving in ``need``: ``'turning'`` or ``'straight driving'``).
    """

    name: str
    std: float
    limit: float
    cause: str
    need: str
    reference_std: float

    def describe(self) -> str:
        """Say what is uncertain and why, in one sentence."""
        if self.cause == 'noise':
            return (f'{self.name} is determined but uncertain: its standard error is '
                    f'{self.std:.3g} (limit {self.limit:.3g}) because the ground truth is '
                    f'noisy; with ground truth of {1000 * REFERENCE_RESIDUAL:.0f} mm the same '
                    f'driving would give {self.reference_std:.2g}')
        return (f'too little {self.need} to identify {self.name}: its standard error is '
                f'{self.std:.3g} (limit {self.limit:.3g})')


def _limit(param, track_width):
    """Return a parameter's standard-error limit and the driving it needs, or (None, '')."""
    if not param.std_checked:
        return None, ''
    if param.excited_by == 'turning':
        return STD_LIMITS['icr'] * (track_width if param.per_track_width else 1.0), 'turning'
    return STD_LIMITS['scale'], 'straight driving'


def _noise(result: FitResult) -> str:
    return (f'the residuals are {1000 * result.rms_position:.0f} mm / '
            f'{math.degrees(result.rms_heading):.1f} deg RMS per segment (ground-truth noise, '
            'and slip the model does not capture)')


def check_identified(result: FitResult, accept_uncertain: bool = False) -> list[Uncertain]:
    """
    Check from the standard errors that the data pin down each ICR and scale parameter.

    Returns the uncertain parameters accepted (``accept_uncertain``). Raises ExcitationError for
    one not determined at all, UncertainError for one beyond :data:`STD_LIMITS`.
    """
    model = result.model
    ratio = result.sigma / REFERENCE_RESIDUAL if result.sigma > 0 else 0.0
    uncertain = []
    for name, std in zip(model.param_names, result.std):
        limit, need = _limit(model.parameter(name), model.track_width)
        if limit is None or std <= limit:
            continue
        if not math.isfinite(std):
            raise ExcitationError(
                f'too little {need} to identify {ros_names(model, [name])}: the data do not '
                f'determine it; drive more, and more varied, '
                f'{"curves and turns in place" if need == "turning" else "straight lines"}')
        reference = std / ratio if ratio > 1.0 else std
        uncertain.append(Uncertain(ros_names(model, [name]), float(std), limit,
                                   'noise' if reference <= limit else 'excitation', need,
                                   float(reference)))
    if uncertain and not accept_uncertain:
        worst = max(uncertain, key=lambda u: u.std / u.limit)
        more = (worst.std / worst.limit) ** 2
        if all(u.cause == 'noise' for u in uncertain):
            advice = (f'{_noise(result)}; better ground truth, or about {more:.1f} x as much '
                      'driving, would bring it within the limit; or accept the fit '
                      '(--accept-uncertain)')
        else:
            what = {'turning': 'curves and turns in place', 'straight driving': 'straight lines'}
            kinds = ' and '.join(what[n] for n in sorted({u.need for u in uncertain
                                                          if u.cause != 'noise'}))
            advice = (f'{_noise(result)}; drive more, and more varied, {kinds}, or accept '
                      'the fit (--accept-uncertain)')
        raise UncertainError('; '.join(u.describe() for u in uncertain) + '; ' + advice)
    return uncertain


AT_BOUND = 1e-3
"""A parameter within this (relative to the bound, at least absolute) of a bound ends on it."""


def _bound_cause(param, side: str) -> str:
    """Say what usually puts a parameter on one of its bounds."""
    if param.name.startswith('scale'):
        return ('the encoders report about twice the travel: a diameter given as '
                '--sprocket-radius (or the ticks per revolution halved)' if side == 'lower' else
                'the encoders report about half the travel: a radius given where the diameter '
                'belongs (or the ticks per revolution doubled)')
    if param.name in ('y_left', 'y_right', 'alpha'):
        # chi = 1 (an ideal drive) is y_left's lower bound, y_right's and alpha's upper one.
        ideal = (side == 'lower') == (param.name == 'y_left')
        return ('the robot turns more than an ideal drive of this track width: --track-width '
                'too large (off by a factor?), or the left and right tracks swapped'
                if ideal else
                'the robot turns far less than the tracks say: --track-width too small by a '
                'factor, or a wrong sprocket radius')
    return 'the data push it out of the physical range: a wrong vehicle dimension or sides swapped'


PINNED = 3.0
"""Standard errors beyond a bound the unbounded optimum must lie for a fit to be pinned there."""


def _unbounded_step(result: FitResult, segments: Segments) -> np.ndarray:
    """Return the Gauss-Newton step from ``result.p`` with no bounds, over the inlier rows."""
    problem = SegmentProblem(result.model, segments, result.heading_weight)
    r = problem.residuals(result.p)
    jac = problem.jacobian(result.p)
    rows = np.repeat((np.abs(r.reshape(-1, 3)) <= 3.0 * result.f_scale).all(axis=1), 3)
    if not np.any(rows):
        rows[:] = True
    step, *_ = np.linalg.lstsq(jac[rows], r[rows], rcond=None)
    return -step   # the Jacobian is that of the residuals, measured minus predicted


def check_bounds(result: FitResult, segments: Segments,
                 accept_uncertain: bool = False) -> list[str]:
    """
    Refuse a fit pinned on a bound of its search space, naming the likely cause.

    A parameter on a bound is pinned when the unbounded optimum (one Gauss-Newton step from
    the fit, every parameter free) lies more than :data:`PINNED` standard errors beyond it:
    the data want a value the physics excludes (a diameter given as the radius puts both
    scales on 0.5). A parameter that merely touches a physical bound (a track that does not
    slip: its ICR on ``+-track_width / 2``) is not refused.

    Returns the descriptions of the pinned parameters (accepted with ``accept_uncertain``, to
    be reported); raises :class:`UncertainError` otherwise (identify_icr's exit 3).
    """
    lo, hi = bounds(result.model)
    on = [(i, side, edge) for i, (value, a, b) in enumerate(zip(result.p, lo, hi))
          for side, edge in (('lower', a), ('upper', b))
          if math.isfinite(edge) and abs(value - edge) <= AT_BOUND * max(1.0, abs(edge))]
    if not on:
        return []
    target = result.p + _unbounded_step(result, segments)
    found = []
    for i, side, edge in on:
        beyond = (edge - target[i]) if side == 'lower' else (target[i] - edge)
        std = result.std[i] if len(result.std) > i and np.isfinite(result.std[i]) else 0.0
        if beyond <= PINNED * std:
            continue
        name = result.model.param_names[i]
        found.append(f'{ros_names(result.model, [name])} ended on its {side} bound {edge:.4g} '
                     f'(the data want {target[i]:.4g}): likely '
                     f'{_bound_cause(result.model.parameter(name), side)}')
    if found and not accept_uncertain:
        raise UncertainError('the fit ended on a bound of its search space: '
                             + '; '.join(found) + ' (--accept-uncertain writes it anyway)')
    return found


def fit(model: MotionModel, segments: Segments, *, p0=None, method: str = 'lsq',
        heading_weight: float | None = DEFAULT_HEADING_WEIGHT, loss: str = 'soft_l1',
        f_scale: float | None = None, max_nfev: int | None = None, rounds: int = 2,
        seed: int = 0, check: bool = True) -> FitResult:
    """
    Fit a motion model to segments: robust, bounded least squares of Martinez eq. (17).

    Parameters
    ----------
    model : MotionModel
        What to fit.
    segments : Segments
        The data, stationary segments removed.
    p0 : array_like, optional
        Starting point (default :func:`initial_guess`), clipped into :func:`bounds`.
    method : {'lsq', 'de'}
        Trust-region least squares with the analytic Jacobian, or differential evolution
        over :func:`search_box` (slow; the paper's genetic algorithm's counterpart).
    heading_weight : float or None
        ``lambda``, m/rad, > 0; None: :func:`auto_heading_weight` at the start of each round.
    loss : str
        One of :data:`LOSSES` (soft-L1 by default).
    f_scale : float, optional
        Loss scale; default twice the robust std of the weighted residuals, per round.
    max_nfev : int, optional
        Evaluation budget per round; default 100 x (parameters + 1).
    rounds : int
        Rounds of (re)estimating ``lambda`` and ``f_scale`` then fitting, warm-started.
    seed : int
        Seed of the differential evolution.
    check : bool
        Apply :func:`check_identified`.

    Raises
    ------
    FitError
        When the optimiser does not converge.
    ExcitationError
        When ``check`` and a parameter is not identified.

    """
    if method not in METHODS:
        raise ValueError(f'method must be one of {", ".join(METHODS)}, got {method!r}')
    if loss not in LOSSES:
        raise ValueError(f'loss must be one of {", ".join(LOSSES)}, got {loss!r}')
    started = time.perf_counter()
    # Auto (None) starts unweighted, lambda = 1, as auto_heading_weight wants its residuals.
    problem = SegmentProblem(model, segments, 1.0 if heading_weight is None else heading_weight)
    lo, hi = bounds(model)
    p = initial_guess(model, segments) if p0 is None else np.asarray(p0, dtype=float)
    p = np.clip(p, lo, hi)
    nfev = 0
    message = 'nothing to fit'
    scale = f_scale or 1.0
    n_rounds = rounds if model.n_params else 1
    from scipy import optimize   # lazily: the nodes import this module, never fit
    for _ in range(n_rounds):
        if heading_weight is None:
            problem.heading_weight = 1.0
            problem.heading_weight = auto_heading_weight(problem.residuals(p))
        r = problem.residuals(p)
        scale = f_scale or max(2.0 * _mad_sigma(r), 1e-9)
        if not model.n_params:
            break
        if method == 'lsq':
            res = optimize.least_squares(
                problem.residuals, p, jac=problem.jacobian, bounds=(lo, hi), loss=loss,
                f_scale=scale, x_scale='jac', method='trf',
                max_nfev=max_nfev or 100 * (model.n_params + 1))
            nfev += res.nfev
            message = res.message
            if res.status <= 0 or not np.all(np.isfinite(res.x)):
                raise FitError(f'the {model.name} fit did not converge: {res.message} '
                               f'({res.nfev} evaluations)')
            p = res.x
        else:
            box_lo, box_hi = search_box(model)
            res = optimize.differential_evolution(
                lambda q: robust_cost(problem.residuals(q), loss, scale),
                list(zip(box_lo, box_hi)), seed=seed, polish=False, tol=1e-8,
                maxiter=max_nfev or 300)
            nfev += res.nfev
            message = res.message
            if not res.success or not np.all(np.isfinite(res.x)):
                raise FitError(f'the {model.name} fit did not converge: {res.message} '
                               f'({res.nfev} evaluations)')
            p = res.x
    r = problem.residuals(p)
    rows = np.abs(r.reshape(-1, 3)) <= 3.0 * scale
    inlier = rows.all(axis=1)
    if not np.any(inlier):
        inlier[:] = True
    r3 = r.reshape(-1, 3)
    result = FitResult(
        model=model, p=p, method=method, loss=loss, heading_weight=problem.heading_weight,
        f_scale=scale, cost=robust_cost(r, loss, scale),
        rms_position=float(np.sqrt(np.mean(r3[inlier, :2] ** 2))),
        rms_heading=float(np.sqrt(np.mean(r3[inlier, 2] ** 2))) / problem.heading_weight,
        segments=len(segments), inliers=int(inlier.sum()), nfev=nfev,
        message=str(message))
    if model.n_params:
        result.std, result.sigma = _standard_errors(problem.jacobian(p), r, np.repeat(inlier, 3),
                                                    with_sigma=True)
    result.seconds = time.perf_counter() - started
    if check:
        check_identified(result)
    return result
