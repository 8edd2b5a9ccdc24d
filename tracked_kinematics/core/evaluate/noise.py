"""
The noise model's constants fitted to recordings: windows, held-out data, the fit.

The windows are evaluate_model's (:func:`.pieces.moving_windows` over the pieces of
:func:`.pieces.cut`, the odometry of :func:`.pieces.odometry`), each with its final error
and the covariance bases of :func:`..noise_model.window_bases`; :func:`held_out_windows`
scores each stretch of data with a kinematic model fitted without it, and
:func:`fit_noise` fits the constants of :class:`..noise_model.NoiseModel` to them
(maximum a posteriori: the windowed final errors Student-t with the propagated covariance).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .pieces import cut, moving_windows, odometry
from ..identify.holdout import crop_recording
from ..kinematics import IcrParams
from ..noise_model import (consistency, covariances, FITTED, heading_consistency, NoiseModel,
                           PRIOR, TERMS, window_bases)


@dataclass(frozen=True)
class ErrorWindows:
    """
    ErrorWindows of odometry against a reference: final errors and covariance bases.

    Attributes
    ----------
    errors : ndarray, shape (W, 3)
        Final error of the odometry's motion over each window, in the frame of its start:
        ``(x, y, theta)``, m, m, rad (odometry minus reference).
    bases : ndarray, shape (W, len(TERMS), 3, 3)
        :func:`window_bases`.
    length : ndarray, shape (W,)
        Window length asked for, s.
    t0 : ndarray, shape (W,)
        Start time of each window, s.
    group : ndarray of int, shape (W,)
        The stretch of data (piece) each window lies in: windows of different groups do not
        overlap.

    """

    errors: np.ndarray
    bases: np.ndarray
    length: np.ndarray
    t0: np.ndarray
    group: np.ndarray

    @classmethod
    def concatenate(cls, parts) -> ErrorWindows:
        """Join windows."""
        parts = [p for p in parts if len(p)]
        if not parts:
            return cls(np.zeros((0, 3)), np.zeros((0, len(TERMS), 3, 3)), np.zeros(0),
                       np.zeros(0), np.zeros(0, np.intp))
        groups, offset = [], 0
        for p in parts:
            groups.append(p.group + offset)
            offset += int(p.group.max()) + 1
        return cls(*(np.concatenate([getattr(p, name) for p in parts])
                     for name in ('errors', 'bases', 'length', 't0')), np.concatenate(groups))

    def __len__(self):
        return len(self.length)

    def select(self, mask) -> ErrorWindows:
        """Return the windows of a mask or index array."""
        return ErrorWindows(self.errors[mask], self.bases[mask], self.length[mask],
                            self.t0[mask], self.group[mask])

    def of_length(self, length: float) -> ErrorWindows:
        """Return the windows of one length, s."""
        return self.select(np.isclose(self.length, length))

    def independent(self) -> float:
        """Return about how many independent windows there are (:meth:`independent_by_length`)."""
        return float(sum(self.independent_by_length().values()))

    def independent_by_length(self) -> dict:
        """
        Return about how many independent windows of each length there are.

        Windows start at every reference sample and overlap; the time their starts span,
        divided by their length, counts the non-overlapping ones.
        """
        out = {}
        for length in np.unique(self.length):
            covered = 0.0
            mine = self.length == length
            for group in np.unique(self.group[mine]):
                steps = np.diff(np.sort(self.t0[mine & (self.group == group)]))
                # Time the starts cover, the gaps between moving stretches left out.
                covered += float(np.sum(steps[steps <= length])) + 1.0 / 20.0
            out[float(length)] = max(1.0, covered / length)
        return out

    def consistency(self, model: NoiseModel) -> dict:
        """Return :func:`consistency` of the position errors under ``model``."""
        return consistency(self.errors[:, :2], covariances(self.bases, model))

    def heading_consistency(self, model: NoiseModel) -> dict:
        """Return :func:`heading_consistency` of the heading errors under ``model``."""
        return heading_consistency(self.errors[:, 2],
                                   self.bases[:, :, 2, 2] @ model.constants + 1e-12)


def piece_windows(piece, icr: IcrParams, lengths,
                  min_speed: float | None = 0.1) -> ErrorWindows:
    """
    Return the windows evaluate_model scores on a piece, their errors and covariance bases.

    The windows of :func:`.pieces.moving_windows` (evaluate_model's: from every
    ground-truth sample, ``length`` s, where the tracks move at ``min_speed`` m/s on average)
    and the odometry of :func:`.pieces.odometry` with the constant model ``icr``.

    Parameters
    ----------
    piece : Piece
        A gap-free piece (:func:`.pieces.cut`).
    icr : IcrParams
        The model the odometry runs with.
    lengths : sequence of float
        Window lengths, s.
    min_speed : float or None
        As :func:`.pieces.moving_windows`.

    """
    params = (icr.y_left, icr.y_right, icr.x, icr.scale_left, icr.scale_right)
    path = odometry(piece, params)
    d_left, d_right, dt = piece.steps
    parts = []
    for length in lengths:
        i, j, _ = moving_windows(piece, float(length), min_speed)
        if len(i) == 0:
            continue
        bases, _ = window_bases(icr, d_left, d_right, dt, piece.at[i], piece.at[j])
        parts.append(ErrorWindows(_motion(path, i, j) - _motion(piece.truth, i, j), bases,
                                  np.full(len(i), float(length)), piece.t[i],
                                  np.zeros(len(i), np.intp)))
    return ErrorWindows.concatenate(parts)


def recording_windows(recordings, icr: IcrParams, lengths, min_speed: float | None = 0.1,
                      track_width: float | None = None) -> ErrorWindows:
    """
    Return the windows evaluate_model scores on recordings with one model (errors, bases).

    Parameters
    ----------
    recordings : sequence of Recording
        Their reference's delay already taken off.
    icr : IcrParams
        The model the odometry runs with.
    lengths : sequence of float
        Window lengths, s.
    min_speed : float or None
        As :func:`.pieces.moving_windows`.
    track_width : float, optional
        m, for the heading glitches among the reference's jumps
        (:func:`.pieces.cut`).

    """
    return ErrorWindows.concatenate(
        piece_windows(piece, icr, lengths, min_speed)
        for k, rec in enumerate(recordings)
        for piece in cut(rec, k, True, track_width).pieces)


def held_out_windows(recordings, fit_icr, lengths, min_speed: float | None = 0.1,
                     track_width: float | None = None, blocks: int = 5) -> ErrorWindows:
    """
    Return windows of odometry whose kinematic model was fitted without them: to fit noise on.

    With two recordings or more, each recording is scored with the model fitted on the
    others (leave one out: the spread of slip from drive to drive is in the errors, as a
    new drive will see it). With one, its time is cut into ``blocks`` blocks and each is
    scored with the model fitted on the rest (the identification's held-out blocks,
    :class:`..identify.holdout.HoldOut`, in turn).

    Parameters
    ----------
    recordings : sequence of Recording
        Their reference's delay already taken off.
    fit_icr : callable
        ``fit_icr(recordings) -> IcrParams``: the identification (e.g. identify_icr's
        ``identify(recordings, ...).icr`` with no delay to remove).
    lengths, min_speed, track_width
        As :func:`recording_windows`.
    blocks : int
        Blocks of a single recording (>= 2).

    """
    recordings = list(recordings)
    if len(recordings) >= 2:
        return ErrorWindows.concatenate(
            recording_windows([rec], fit_icr(recordings[:k] + recordings[k + 1:]), lengths,
                              min_speed, track_width)
            for k, rec in enumerate(recordings))
    (rec,) = recordings
    t0, t1 = float(rec.enc_t[0]), float(rec.enc_t[-1])
    edges = np.linspace(t0, t1, blocks + 1)
    parts = []
    for a, b in zip(edges[:-1], edges[1:]):
        rest = (([crop_recording(rec, t0, a)] if a > t0 else [])
                + ([crop_recording(rec, b, t1)] if b < t1 else []))
        parts.append(recording_windows([crop_recording(rec, a, b)], fit_icr(rest), lengths,
                                       min_speed, track_width))
    return ErrorWindows.concatenate(parts)


def _motion(path, i, j):
    """Motion from samples ``i`` to ``j`` of a path in the frame of ``i``: (W, 3)."""
    c, s = np.cos(path[i, 2]), np.sin(path[i, 2])
    ex, ey = path[j, 0] - path[i, 0], path[j, 1] - path[i, 1]
    return np.column_stack([c * ex + s * ey, -s * ex + c * ey, path[j, 2] - path[i, 2]])


PRIOR_WIDTH = math.log(10.0)
"""Standard deviation of the prior of each log-constant: a factor of 10."""


@dataclass(frozen=True)
class NoiseFit:
    """
    Result of :func:`fit_noise`.

    Attributes
    ----------
    model : NoiseModel
        The fitted constants (the prior's where held).
    fitted : tuple of str
        The terms fitted to the data.
    held : tuple of str
        The terms held at the prior's value (not determined by the reference).
    windows : int
        ErrorWindows fitted on.
    independent : float
        About how many of them are independent (:meth:`ErrorWindows.independent`).
    errors : str
        What was compared: ``'position'``, ``'pose'`` or ``'heading'`` (:data:`ERRORS`).

    """

    model: NoiseModel
    fitted: tuple
    held: tuple
    windows: int
    independent: float
    errors: str

    def values(self, lengths=(5.0, 10.0)) -> dict:
        """
        Return the terrain file's ``covariance.*`` entries: the constants and their provenance.

        Parameters
        ----------
        lengths : sequence of float
            The window lengths fitted on, s.

        """
        return {**{f'covariance.{t}': getattr(self.model, t) for t in TERMS},
                'covariance.fit.fitted': list(self.fitted),
                'covariance.fit.held': list(self.held),
                'covariance.fit.errors': self.errors,
                'covariance.fit.windows': self.windows,
                'covariance.fit.independent_windows': round(self.independent, 1),
                'covariance.fit.window_lengths': [float(w) for w in lengths]}


ERRORS = {'position': slice(0, 2), 'pose': slice(0, 3), 'heading': slice(2, 3)}
"""What a fit compares (:func:`fit_noise`): the components of the windows' final errors."""


DOF = 10.0
"""Degrees of freedom of the Student-t likelihood of :func:`fit_noise`."""


def negative_log_likelihoods(errors, covariances, dof) -> np.ndarray:
    """
    Return ``-2 log p`` of each window's error but for constants: Gaussian or Student-t.

    With ``dof``, a multivariate Student-t whose covariance is ``covariances`` (its scale
    matrix ``covariances (dof - 2) / dof``); None: a Gaussian. LinAlgError for a covariance
    that is not positive definite (or not finite).
    """
    if dof is not None:
        covariances = covariances * ((dof - 2.0) / dof)
    log_det, q = _cholesky_terms(errors, covariances)
    if dof is None:
        return log_det + q
    return log_det + (dof + errors.shape[1]) * np.log1p(q / dof)


def _cholesky_terms(errors, covariances):
    """
    Return ``log det P`` and ``e^T P^-1 e`` of each window.

    The Cholesky factor ``P = L L^T`` and ``z = L^-1 e`` element by element over all windows
    at once (the windows' are 1-3-dimensional; numpy's batched ``cholesky`` and ``solve``
    call LAPACK once per 3 x 3, and the noise fit evaluates this some 200 times);
    LinAlgError for a matrix that is not positive definite, or not finite (where LAPACK
    lets a NaN through).
    """
    n = errors.shape[1]
    a, e = covariances, errors
    pivots, z, rows = [], [], []
    for i in range(n):
        row = []
        for j in range(i):
            acc = a[:, i, j] - sum(row[k] * rows[j][k] for k in range(j))
            row.append(acc / pivots[j])
        d = a[:, i, i] - sum(v * v for v in row)
        if not np.all(d > 0.0):
            raise np.linalg.LinAlgError('the covariance is not positive definite')
        pivot = np.sqrt(d)
        z.append((e[:, i] - sum(row[k] * z[k] for k in range(i))) / pivot)
        pivots.append(pivot)
        rows.append(row)
    q = sum(v * v for v in z)
    log_det = 2.0 * sum(np.log(v) for v in pivots)
    return log_det, q


def _negative_log_posterior(log_c, prior_c, free, groups, width, dof):
    c = prior_c.copy()
    c[free] = np.exp(log_c)
    total = 0.0
    for weight, errors, bases in groups:
        cov = np.einsum('wmij,m->wij', bases, c) + 1e-12 * np.eye(errors.shape[1])
        try:
            total += 0.5 * weight * np.mean(negative_log_likelihoods(errors, cov, dof))
        except np.linalg.LinAlgError:
            return np.inf
    return total + 0.5 * np.sum((log_c - np.log(prior_c[free])) ** 2) / (width * width)


def fit_noise(windows: ErrorWindows, prior: NoiseModel | None = None, free=FITTED,
              errors: str = 'pose', width: float = PRIOR_WIDTH,
              dof: float | None = DOF) -> NoiseFit:
    """
    Fit the constants of the noise model to windowed final errors (maximum a posteriori).

    The final error of each window is taken as zero-mean with the propagated covariance
    (:func:`..noise_model.window_bases`), Student-t distributed with ``dof`` degrees of
    freedom: robust to the few windows a reference's glitch or a bad stretch of the
    kinematic fit spoils (a Gaussian would widen every ellipse for them; the identification
    uses a robust loss for the same reason). The likelihood of each window length
    is the mean over its windows times the number of independent ones (overlapping windows
    are not independent: a composite likelihood), and each log-constant has a Gaussian
    prior about ``prior``'s value, ``width`` wide: a term the data hardly inform (no tight
    turns: ``slip``) stays near its prior.

    Parameters
    ----------
    windows : ErrorWindows
        The windows (:func:`held_out_windows`), on data the kinematic model was not fitted
        to.
    prior : NoiseModel, optional
        Centre of the prior, and the value of the terms not fitted; default
        :data:`..noise_model.PRIOR`.
    free : sequence of str
        The terms fitted (of :data:`..noise_model.TERMS`; by default all but ``scale``,
        which a calibration's prior gives).
    errors : str
        What is compared (:data:`ERRORS`): ``'pose'``, position and heading (a pose
        reference: the heading errors inform ``turn``, which the positions hardly do),
        ``'position'`` or ``'heading'`` (a gyro reference: the heading's variance does not
        depend on ``slip``, which is held).
    width : float
        Standard deviation of each log-constant's prior.
    dof : float or None
        Degrees of freedom of the Student-t likelihood (> 2); None: Gaussian.

    Returns
    -------
    NoiseFit

    Raises
    ------
    ValueError
        Without windows, for an unknown term or kind of errors, for ``dof <= 2``, or for a
        term fitted whose prior is 0.

    """
    if len(windows) == 0:
        raise ValueError('no windows to fit the noise model on')
    if errors not in ERRORS:
        raise ValueError(f'errors must be one of {", ".join(ERRORS)}, got {errors!r}')
    if dof is not None and not dof > 2.0:
        raise ValueError(f'dof must be > 2 (a finite covariance), got {dof!r}')
    prior = prior or PRIOR
    unknown = set(free) - set(TERMS)
    if unknown:
        raise ValueError(f'unknown noise terms: {", ".join(sorted(unknown))}')
    free = tuple(t for t in TERMS
                 if t in set(free) and not (errors == 'heading' and t == 'slip'))
    prior_c = prior.constants
    index = np.array([TERMS.index(t) for t in free], np.intp)
    if np.any(prior_c[index] <= 0.0):
        raise ValueError('a fitted term needs a prior value > 0')
    # The scale of a prior without one is off, not held.
    held = tuple(t for t in TERMS if t not in free
                 and not (t == 'scale' and prior_c[TERMS.index(t)] == 0.0))
    part = ERRORS[errors]
    groups = []
    for length, n_eff in windows.independent_by_length().items():
        mine = windows.of_length(length)
        groups.append((n_eff, mine.errors[:, part], mine.bases[:, :, part, part]))
    c = prior_c.copy()
    if len(index):
        from scipy.optimize import minimize   # lazily, as every scipy of core
        best = minimize(_negative_log_posterior, np.log(prior_c[index]),
                        args=(prior_c, index, groups, width, dof), method='Nelder-Mead',
                        options={'xatol': 1e-4, 'fatol': 1e-9, 'maxiter': 4000})
        c[index] = np.exp(best.x)
    model = NoiseModel(**dict(zip(TERMS, (float(v) for v in c))), floor=prior.floor)
    return NoiseFit(model, free, held, len(windows), windows.independent(), errors)
