"""
The whole identification: time, check, fit, hold out, compare (Martinez et al. 2005, sec. 4.2).

:func:`identify` measures the delay of the ground-truth stamps behind the encoders and
removes it (:mod:`.delay`), cuts the recordings into segments inside their pieces
(:mod:`.segments`), checks that they excite what is fitted (:mod:`.excitation`), fits the
requested model by the least squares of eq. (17) (:mod:`.fitting`), fits the baseline a user
already has, diff_drive_controller tuned (:mod:`.tuned_diff_drive`), and measures every
compared model on held-out time blocks (:mod:`.holdout`), the comparison of Martinez sec. 6
and Fink & Stump sec. IV-B.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import time

import numpy as np

from .delay import correct_ground_truth, DelayEstimate, estimate_delays, fixed_delay
from .excitation import check_excitation, Excitation
from .fitting import check_identified, fit, FitResult
from .holdout import ErrorStats, HoldOut, MIN_SEGMENTS, MIN_WINDOWS, prediction_errors
from .problem import DEFAULT_HEADING_WEIGHT
from .search_space import build_model, COMPARE_MODELS
from .segments import build_segments, covered_spans, ground_truth_jumps, over_jumps, Segments
from ..errors import ExcitationError, FitError, IdentificationError
from ..kinematics import IcrParams


MIN_SPEED = 0.1
"""m/s of mean track speed from which a held-out window counts as moving (as evaluate_model's
``--min-speed``)."""


@dataclass
class ModelEvaluation:
    """
    One model fitted on the training blocks and measured on the held-out ones.

    Attributes
    ----------
    name : str
        Model name.
    fit : FitResult or None
        The training fit of the first fold (None for ``ideal``, or when it failed: see
        ``error``).
    fits : list of FitResult
        The training fit of every fold.
    segments, windows : ErrorStats or None
        Errors per held-out segment and per held-out window, over all folds (``n == 0``:
        none).
    error : str
        Why the fit failed, or ''.

    """

    name: str
    fit: FitResult | None = None
    segments: ErrorStats | None = None
    windows: ErrorStats | None = None
    error: str = ''
    fits: list = field(default_factory=list)


@dataclass(frozen=True)
class DataTime:
    """
    How much data there is: first to last sample, both streams, driving.

    Attributes
    ----------
    span : float
        Sum over recordings of first to last sample of either stream, s (gaps included).
    covered : float
        Time where both streams have samples without a gap, s (the pieces).
    driving : float
        Duration of the moving segments, s.
    pieces : int
        Stretches where both streams cover (:func:`.segments.covered_spans`).
    longest_piece : float
        s.

    """

    span: float
    covered: float
    driving: float
    pieces: int
    longest_piece: float


@dataclass
class Identification:
    """
    Result of :func:`identify`.

    Attributes
    ----------
    fit : FitResult
        The requested model, fitted on all moving segments.
    icr : IcrParams
        The terrain model to write: the fitted model itself when it is a constant-ICR model,
        otherwise the ``icr_scales`` fit of the same data (see ``icr_source``).
    icr_source : str
        Name of the model ``icr`` comes from.
    excitation : Excitation
        How much the data move and turn.
    holdout : HoldOut or None
        The held-out blocks (None when nothing is held out).
    evaluations : list of ModelEvaluation
        Every compared model on the held-out blocks, ``ideal`` first.
    segment_length, window : float
        Segment and evaluation window durations, s.
    seconds : dict
        Wall time of each phase, s.
    delay : DelayEstimate
        The delay of the ground-truth stamps behind the encoders, all recordings together;
        removed before all else unless ``delays`` (``delay.delay == 0`` when off or not
        determined).
    delays : list of DelayEstimate
        Each recording's own delay, removed from it instead, when every recording
        determines its own (:func:`.delay.estimate_delays`); else empty.
    ddc : FitResult or None
        diff_drive_controller's multipliers fitted on all moving segments (None when the
        fit failed: ``ddc_error``).
    ddc_error : str
        Why the tuned-DDC fit failed, or ''.
    uncertain : list of Uncertain
        Parameters of ``fit`` determined but uncertain, accepted (``accept_uncertain``).
    time : DataTime
        How much data there is.
    recordings : list of Recording
        The recordings with the delay removed: what was fitted.
    jumps : int
        Ground-truth jumps found (:func:`.segments.ground_truth_jumps`).
    jump_segments : int
        Segments over a jump, left out of the fit and of the evaluation (windows over a
        jump are left out too).
    min_speed : float or None
        Mean track speed from which a held-out window was scored, m/s (None: every window).
    windows_total : int
        Held-out windows over all folds before that selection (those over a jump left out).

    """

    fit: FitResult
    icr: IcrParams
    icr_source: str
    excitation: Excitation
    holdout: HoldOut | None
    evaluations: list
    segment_length: float | None
    window: float
    seconds: dict
    delay: DelayEstimate = field(default_factory=lambda: fixed_delay(0.0))
    delays: list = field(default_factory=list)
    ddc: FitResult | None = None
    ddc_error: str = ''
    uncertain: list = field(default_factory=list)
    time: DataTime | None = None
    recordings: list = field(default_factory=list, repr=False)
    jumps: int = 0
    jump_segments: int = 0
    min_speed: float | None = None
    windows_total: int = 0

    def evaluation(self, name: str) -> ModelEvaluation | None:
        """Return the evaluation of one model, or None."""
        return next((e for e in self.evaluations if e.name == name), None)


def _data_time(recordings, moving) -> DataTime:
    span = covered = longest = 0.0
    pieces = 0
    for rec in recordings:
        times = [t for t in (rec.enc_t, rec.gt_t) if len(t)]
        if times:
            span += max(t[-1] for t in times) - min(t[0] for t in times)
        start, end = covered_spans(rec)
        covered += float(np.sum(end - start))
        pieces += len(start)
        longest = max([longest] + list(end - start))
    return DataTime(float(span), covered, float(np.sum(moving.t1 - moving.t0)), pieces,
                    float(longest))


def identify(recordings, model: str = 'icr_scales', track_width: float = 0.42, *,
             base: IcrParams | None = None, method: str = 'lsq',
             segment_length: float | None = 1.0,
             heading_weight: float | None = DEFAULT_HEADING_WEIGHT, loss: str = 'soft_l1',
             min_travel: float = 0.01, holdout: float = 0.2, holdout_block: float = 30.0,
             window: float = 10.0, compare=COMPARE_MODELS, max_nfev: int | None = None,
             ground_truth_delay: float | str | None = 0.0,
             accept_uncertain: bool = False,
             min_speed: float | None = MIN_SPEED) -> Identification:
    """
    Identify a terrain model from recordings: time, check, fit, hold out, compare.

    0. Measure the delay of the ground-truth stamps behind the encoders
       (``ground_truth_delay='auto'``: :func:`.delay.estimate_delays`, each recording's
       own when each determines it) or take the one given, and remove it from the
       ground-truth stamps.
    1. Cut the recordings into segments inside their pieces (:func:`build_segments`) and
       drop those over a ground-truth jump (:func:`.segments.ground_truth_jumps`) and
       stationary ones (both tracks travel less than ``min_travel``): they carry no
       information and would shrink the robust scale.
    2. Check the excitation for ``model`` (:func:`check_excitation`): refuse data with no
       motion, no turning or no straight driving, which cannot determine it.
    3. Fit ``model`` on all moving segments, starting from ``base`` when given, and check
       its standard errors (:func:`.fitting.check_identified`: a parameter determined but
       uncertain is refused unless ``accept_uncertain``).
    4. Fit the tuned diff_drive_controller (:class:`.tuned_diff_drive.TunedDiffDrive`) on the
       same data.
    5. Hold out time blocks (:class:`HoldOut`: cross-validated when one fold would give
       fewer than :data:`.holdout.MIN_WINDOWS` scored windows and
       :data:`.holdout.MIN_SEGMENTS` segments), fit every model of ``compare``
       on the rest with the heading weight of step 3 (one round of robust least squares
       each) and measure each on the held-out segments and on the held-out windows of
       ``window`` s in which the vehicle moves (:func:`moving`; ``min_speed=None``: every
       window), none over a ground-truth jump.

    Parameters
    ----------
    recordings : sequence of Recording
        The data.
    model : str
        Model to fit (a registered name: :func:`.search_space.fit_models`, ``symmetric``).
    track_width : float
        m.
    base : IcrParams, optional
        Starting point of a model that can start from it
        (:meth:`..models.MotionModel.start_from`), and the fixed scales of the ``icr`` model.
    method, loss, max_nfev
        See :func:`fit`.
    heading_weight : float or None
        ``lambda`` of eq. (17), m/rad; None for :func:`.fitting.auto_heading_weight`. The
        default, 1 m/rad (:data:`DEFAULT_HEADING_WEIGHT`), is the paper's unweighted sum.
        On simulated data with a model mismatch (adaptive ICRs fitted by constant ones) and
        ground-truth noise, it gave held-out odometry as good as any other weight tried (0.3
        to 3), while the noise-balancing ``auto`` weight dropped to its floor on long
        segments, where the position residuals of the mismatch grow, and cost 10 % of final
        position accuracy.
    segment_length : float or None
        See :func:`build_segments`.
    min_travel : float
        Stationary threshold, m.
    holdout : float
        Fraction of the time blocks one fold holds out; 0 disables the evaluation.
    holdout_block : float
        Longest block, s of driving.
    window : float
        Evaluation window, s.
    compare : sequence of str
        Models evaluated on the held-out blocks.
    ground_truth_delay : float, 'auto' or None
        s of ground-truth stamps behind the encoders to remove; ``'auto'`` estimates it
        (when it cannot be determined, none is removed: ``delay.determined`` says so);
        0 or None removes none.
    accept_uncertain : bool
        Accept a fit whose parameters are determined but uncertain (listed in
        ``uncertain``) instead of refusing it.
    min_speed : float or None
        Score the held-out windows whose mean track speed is at least this, m/s
        (:data:`MIN_SPEED`: those in which the vehicle moves, so that a figure does not
        depend on how long it stood still); None scores idle windows too.

    Raises
    ------
    ExcitationError, FitError
        See :func:`check_excitation`, :func:`.fitting.check_identified` and :func:`fit`.
    ValueError
        For a ``ground_truth_delay`` or ``min_speed`` that is neither a number nor its word.

    """
    if min_speed is not None and not (np.isfinite(min_speed) and min_speed >= 0):
        raise ValueError(f'min_speed must be a finite number >= 0 (m/s) or None, got '
                         f'{min_speed!r}')
    seconds = {}
    started = time.perf_counter()
    recordings = list(recordings)
    if isinstance(ground_truth_delay, str):
        if ground_truth_delay != 'auto':
            raise ValueError(f"ground_truth_delay must be a number of seconds or 'auto', got "
                             f'{ground_truth_delay!r}')
        delay, each = estimate_delays(recordings)
    else:
        delay, each = fixed_delay(ground_truth_delay or 0.0), []
    removed = [e.delay for e in each] if each else [delay.delay] * len(recordings)
    recordings = [correct_ground_truth([r], d)[0] for r, d in zip(recordings, removed)]
    seconds['delay'] = time.perf_counter() - started

    started = time.perf_counter()
    scales = (base.scale_left, base.scale_right) if base is not None else (1.0, 1.0)
    target = build_model(model, track_width, scales)
    all_segments = build_segments(recordings, segment_length)
    if len(all_segments) == 0:
        raise ExcitationError(_why_no_segments(recordings, segment_length))
    # The ground truth over a jump (a re-localisation, a glitch) says nothing of the motion.
    jumped = over_jumps(all_segments, recordings, track_width)
    all_segments = all_segments.select(~jumped)
    excitation = Excitation.of(all_segments, min_travel)
    check_excitation(target, excitation)
    segments = all_segments.select(all_segments.travel >= min_travel)
    seconds['segments'] = time.perf_counter() - started

    def start_of(m):
        return None if base is None else m.start_from(base)

    options = {'method': method, 'loss': loss, 'max_nfev': max_nfev}
    started = time.perf_counter()
    result = fit(target, segments, p0=start_of(target), heading_weight=heading_weight,
                 check=False, **options)
    uncertain = check_identified(result, accept_uncertain)
    # Every other fit weighs heading as this one does (its loss scale is its own: a worse
    # model has larger residuals, which are not outliers).
    options['heading_weight'] = result.heading_weight
    try:
        icr, source = result.icr, target.name
        if not target.constant_icr:
            icr_model = build_model('icr_scales', track_width)
            try:
                icr_fit = fit(icr_model, segments, p0=start_of(icr_model), check=False,
                              **options)
                check_identified(icr_fit, accept_uncertain)
            except ExcitationError:
                icr_model = build_model('icr', track_width, scales)
                icr_fit = fit(icr_model, segments, p0=start_of(icr_model), check=False,
                              **options)
                check_identified(icr_fit, accept_uncertain)
            icr, source = icr_fit.icr, icr_model.name
    except ValueError as err:
        if isinstance(err, IdentificationError):
            raise
        raise FitError(f'the fit gave an invalid ICR model: {err}') from None
    seconds['fit'] = time.perf_counter() - started

    started = time.perf_counter()
    ddc, ddc_error = None, ''
    try:
        ddc = fit(build_model('tuned_ddc', track_width), segments, check=False, **options)
    except IdentificationError as err:
        ddc_error = str(err)
    seconds['ddc'] = time.perf_counter() - started

    started = time.perf_counter()
    data_time = _data_time(recordings, segments)
    held = None
    evaluations = []
    windows_total = 0

    def scored(windows):
        """Return the windows scored and how many there were apart from jumps (idle too)."""
        windows = windows.select(~over_jumps(windows, recordings, track_width))
        return windows.select(moving(windows, min_speed)), len(windows)

    if holdout > 0:
        # Blocks long enough for windows, unless no window fits in any piece.
        fits = window if data_time.longest_piece >= window else 0.0
        held = HoldOut.choose(segments, holdout, holdout_block, fits)
        if held is not None and len(scored(held.windows(recordings, window))[0]) < MIN_WINDOWS \
                and np.count_nonzero(held.inside(segments, 0)) < MIN_SEGMENTS:
            # Too little held out for a comparison: hold every block out once, in turn.
            held = HoldOut.choose(segments, holdout, holdout_block, fits,
                                  folds=max(2, int(round(1.0 / holdout))))
    if held is not None:
        folds = []
        for f in range(len(held.folds)):
            test = segments.select(held.inside(segments, f))
            windows, total = scored(held.windows(recordings, window, f))
            windows_total += total
            folds.append((segments.select(held.outside(segments, f)), test, windows))
        for name in compare:
            evaluations.append(_evaluate(name, track_width, scales, folds, start_of, options))
    seconds['holdout'] = time.perf_counter() - started
    return Identification(result, icr, source, excitation, held, evaluations, segment_length,
                          window, seconds, delay=delay, delays=each, ddc=ddc, ddc_error=ddc_error,
                          uncertain=uncertain, time=data_time,
                          recordings=recordings,
                          jumps=sum(len(ground_truth_jumps(r, track_width)) for r in recordings),
                          jump_segments=int(np.count_nonzero(jumped)),
                          min_speed=min_speed, windows_total=windows_total)


def moving(windows: Segments, min_speed: float | None) -> np.ndarray:
    """
    Return which windows the vehicle moves in: mean track speed at least ``min_speed``.

    The mean track speed of a window is ``(|V_l| + |V_r|) / 2`` of the nominal track speeds
    averaged over it: half the summed absolute travel of both tracks divided by its duration
    (a turn on the spot moves; a standstill does not), as evaluate_model selects its windows
    (:func:`tracked_kinematics.core.evaluate.pieces.mean_track_speeds`).

    Parameters
    ----------
    windows : Segments
        The windows.
    min_speed : float or None
        m/s; None: every window.

    Returns
    -------
    ndarray of bool

    """
    if min_speed is None:
        return np.ones(len(windows), dtype=bool)
    # As a speed (evaluate_model's mean_track_speeds): no product to overflow.
    with np.errstate(divide='ignore', invalid='ignore'):
        return windows.travel / (windows.t1 - windows.t0) >= min_speed


def _why_no_segments(recordings, segment_length) -> str:
    """Say why recordings give no segment at all: the streams apart, or pieces too short."""
    ranges = []
    for rec in recordings:
        if len(rec.enc_t) < 2 or len(rec.gt_t) < 2:
            continue
        start, end = covered_spans(rec)
        if len(start):
            ranges.append(float(np.max(end - start)))
            continue
        return (f'{rec.name or "a recording"}: the encoders ({rec.enc_t[0]:.2f}-'
                f'{rec.enc_t[-1]:.2f} s) and the ground truth ({rec.gt_t[0]:.2f}-'
                f'{rec.gt_t[-1]:.2f} s) never both have samples: not one clock, or a '
                'ground-truth delay far beyond the search?')
    if not ranges:
        return 'no recording has two encoder and two ground-truth samples'
    return (f'no segment: the pieces where both streams have samples are at most '
            f'{max(ranges):.2f} s long, less than half a segment of {segment_length:g} s; '
            'give a shorter --segment-length')


def _evaluate(name, track_width, scales, folds, start_of, options) -> ModelEvaluation:
    """Fit one model on each fold's training segments; pool its held-out errors."""
    evaluation = ModelEvaluation(name)
    m = build_model(name, track_width, scales)
    errors = {'segments': ([], []), 'windows': ([], [])}
    try:
        for train, test, windows in folds:
            if m.n_params and len(train) == 0:
                raise ExcitationError('no training segments outside the held-out blocks')
            if m.n_params:
                fitted = fit(m, train, p0=start_of(m), check=False, rounds=1, **options)
                evaluation.fits.append(fitted)
                p = fitted.p
            else:
                p = m.initial()
            for key, data in (('segments', test), ('windows', windows)):
                position, heading = prediction_errors(m, p, data)
                errors[key][0].append(position)
                errors[key][1].append(heading)
    except IdentificationError as err:
        evaluation.error = str(err)
        return evaluation
    evaluation.fit = evaluation.fits[0] if evaluation.fits else None
    evaluation.segments = ErrorStats.of(*(np.concatenate(v) for v in errors['segments']))
    evaluation.windows = ErrorStats.of(*(np.concatenate(v) for v in errors['windows']))
    return evaluation
