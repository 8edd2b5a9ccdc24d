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

from dataclasses import dataclass, field, replace
import time

import numpy as np

from .delay import correct_ground_truth, DelayEstimate, estimate_delays, fixed_delay
from .excitation import check_excitation, Excitation
from .fitting import check_bounds, check_identified, fit, FitResult
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
    at_bounds : list of str
        Parameters that ended on a bound of the search space, accepted
        (``accept_uncertain``), with the likely cause (:func:`.fitting.check_bounds`).

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
    at_bounds: list = field(default_factory=list)

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


@dataclass(frozen=True, slots=True)
class IdentifyOptions:
    """
    How :func:`identify` fits and compares: identify_icr's fit and evaluation options.

    Attributes
    ----------
    method : str
        ``lsq`` or ``de`` (:func:`fit`).
    segment_length : float or None
        Segment duration, s; None or 0: every ground-truth sample (:func:`build_segments`).
    heading_weight : float or None
        ``lambda`` of eq. (17), m/rad; None: :func:`.fitting.auto_heading_weight`
        (docs/tools/identify_icr.md on the choice of the default).
    loss : str
        Robust loss (:data:`.problem.LOSSES`).
    min_travel : float
        Segments whose tracks travel less are stationary and left out, m.
    holdout : float
        Fraction of the time blocks one fold holds out; 0: no comparison.
    holdout_block : float
        Longest held-out block, s of driving.
    window : float
        Held-out evaluation window, s.
    compare : tuple of str
        Models compared on the held-out blocks.
    max_nfev : int or None
        Evaluation budget of one optimisation round (None: the method's default).
    ground_truth_delay : float, 'auto' or None
        s of ground-truth stamps behind the encoders to remove; 'auto' estimates it (none
        removed when it cannot be determined); 0 or None: none.
    accept_uncertain : bool
        Accept parameters determined but uncertain (listed) instead of refusing the fit.
    min_speed : float or None
        Score the held-out windows whose mean track speed is at least this, m/s
        (:func:`moving`); None: every window.

    """

    method: str = 'lsq'
    segment_length: float | None = 1.0
    heading_weight: float | None = DEFAULT_HEADING_WEIGHT
    loss: str = 'soft_l1'
    min_travel: float = 0.01
    holdout: float = 0.2
    holdout_block: float = 30.0
    window: float = 10.0
    compare: tuple = COMPARE_MODELS
    max_nfev: int | None = None
    ground_truth_delay: float | str | None = 0.0
    accept_uncertain: bool = False
    min_speed: float | None = MIN_SPEED


def identify(recordings, model: str = 'icr_scales', track_width: float = 0.42, *,
             base: IcrParams | None = None, options: IdentifyOptions = IdentifyOptions(),
             **changes) -> Identification:
    """
    Identify a terrain model from recordings: time, check, fit, hold out, compare.

    Removes the ground-truth delay (:mod:`.delay`), cuts segments and drops those over a
    ground-truth jump and the stationary ones, checks the excitation for ``model``
    (:func:`check_excitation`), fits it on all moving segments (:func:`fit`, then
    :func:`.fitting.check_identified`), fits the tuned diff_drive_controller on the same data,
    and measures every model of ``options.compare`` on held-out time blocks
    (:class:`HoldOut`, cross-validated when one fold holds out too little), with the heading
    weight of the main fit. Steps and figures: docs/tools/identify_icr.md.

    Parameters
    ----------
    recordings : sequence of Recording
        The data.
    model : str
        Model to fit (a registered name: :func:`.search_space.fit_models`, ``symmetric``).
    track_width : float
        m.
    base : IcrParams, optional
        Starting point of a model that can start from it, and the fixed scales of ``icr``.
    options : IdentifyOptions
        How to fit and compare.
    **changes
        Fields of ``options`` to replace (``holdout=0.0``).

    Raises
    ------
    ExcitationError, FitError
        See :func:`check_excitation`, :func:`.fitting.check_identified` and :func:`fit`.
    ValueError
        For a ``ground_truth_delay`` that is neither a number nor 'auto'.

    """
    options = replace(options, **changes) if changes else options
    seconds = {}
    started = time.perf_counter()
    recordings, delay, each = _remove_delay(list(recordings), options.ground_truth_delay)
    seconds['delay'] = time.perf_counter() - started

    started = time.perf_counter()
    scales = (base.scale_left, base.scale_right) if base is not None else (1.0, 1.0)
    target = build_model(model, track_width, scales)
    segments, excitation, jumped = _moving_segments(recordings, target, options, track_width)
    seconds['segments'] = time.perf_counter() - started

    def start_of(m):
        return None if base is None else m.start_from(base)

    settings = {'method': options.method, 'loss': options.loss, 'max_nfev': options.max_nfev}
    started = time.perf_counter()
    result, icr, source, uncertain, at_bounds = _fit_written(
        target, segments, start_of, settings, options, track_width, scales)
    seconds['fit'] = time.perf_counter() - started

    started = time.perf_counter()
    ddc, ddc_error = None, ''
    try:
        ddc = fit(build_model('tuned_ddc', track_width), segments, check=False, **settings)
    except IdentificationError as err:
        ddc_error = str(err)
    seconds['ddc'] = time.perf_counter() - started

    started = time.perf_counter()
    data_time = _data_time(recordings, segments)
    held, evaluations, windows_total = _compare(recordings, segments, data_time, options,
                                                track_width, scales, start_of, settings)
    seconds['holdout'] = time.perf_counter() - started
    return Identification(result, icr, source, excitation, held, evaluations,
                          options.segment_length, options.window, seconds, delay=delay,
                          delays=each, ddc=ddc, ddc_error=ddc_error, uncertain=uncertain,
                          time=data_time, recordings=recordings,
                          jumps=sum(len(ground_truth_jumps(r, track_width)) for r in recordings),
                          jump_segments=int(np.count_nonzero(jumped)),
                          min_speed=options.min_speed, windows_total=windows_total,
                          at_bounds=at_bounds)


def _remove_delay(recordings, ground_truth_delay):
    """Estimate (or take) the ground-truth delay and remove it: (recordings, delay, each)."""
    if isinstance(ground_truth_delay, str):
        if ground_truth_delay != 'auto':
            raise ValueError(f"ground_truth_delay must be a number of seconds or 'auto', got "
                             f'{ground_truth_delay!r}')
        delay, each = estimate_delays(recordings)
    else:
        delay, each = fixed_delay(ground_truth_delay or 0.0), []
    removed = [e.delay for e in each] if each else [delay.delay] * len(recordings)
    return ([correct_ground_truth([r], d)[0] for r, d in zip(recordings, removed)], delay,
            each)


def _moving_segments(recordings, target, options, track_width):
    """Cut the segments, drop those over jumps, check the excitation; keep the moving ones."""
    all_segments = build_segments(recordings, options.segment_length)
    if len(all_segments) == 0:
        raise ExcitationError(_why_no_segments(recordings, options.segment_length))
    # The ground truth over a jump (a re-localisation, a glitch) says nothing of the motion.
    jumped = over_jumps(all_segments, recordings, track_width)
    all_segments = all_segments.select(~jumped)
    excitation = Excitation.of(all_segments, options.min_travel)
    check_excitation(target, excitation)
    return (all_segments.select(all_segments.travel >= options.min_travel), excitation,
            jumped)


def _fit_written(target, segments, start_of, settings, options, track_width, scales):
    """
    Fit the requested model and the constant-ICR model to write; check both.

    Returns ``(result, icr, source, uncertain, at_bounds)`` and sets ``settings``'s heading
    weight to the main fit's: every other fit weighs heading as it does (its loss scale is
    its own: a worse model has larger residuals, which are not outliers).
    """
    accept = options.accept_uncertain
    result = fit(target, segments, p0=start_of(target), heading_weight=options.heading_weight,
                 check=False, **settings)
    uncertain = check_identified(result, accept)
    at_bounds = check_bounds(result, segments, accept)
    settings['heading_weight'] = result.heading_weight
    try:
        icr, source = result.icr, target.name
        if not target.constant_icr:
            icr_model = build_model('icr_scales', track_width)
            try:
                icr_fit = fit(icr_model, segments, p0=start_of(icr_model), check=False,
                              **settings)
                check_identified(icr_fit, accept)
            except ExcitationError:
                icr_model = build_model('icr', track_width, scales)
                icr_fit = fit(icr_model, segments, p0=start_of(icr_model), check=False,
                              **settings)
                check_identified(icr_fit, accept)
            at_bounds += check_bounds(icr_fit, segments, accept)
            icr, source = icr_fit.icr, icr_model.name
    except ValueError as err:
        if isinstance(err, IdentificationError):
            raise
        raise FitError(f'the fit gave an invalid ICR model: {err}') from None
    return result, icr, source, uncertain, at_bounds


def _compare(recordings, segments, data_time, options, track_width, scales, start_of,
             settings):
    """Measure every compared model on held-out blocks: (held, evaluations, windows_total)."""
    window, min_speed, holdout = options.window, options.min_speed, options.holdout
    held, evaluations, windows_total = None, [], 0

    def scored(windows):
        """Return the windows scored and how many there were apart from jumps (idle too)."""
        windows = windows.select(~over_jumps(windows, recordings, track_width))
        return windows.select(moving(windows, min_speed)), len(windows)

    if holdout > 0:
        # Blocks long enough for windows, unless no window fits in any piece.
        fits = window if data_time.longest_piece >= window else 0.0
        held = HoldOut.choose(segments, holdout, options.holdout_block, fits)
        if held is not None and len(scored(held.windows(recordings, window))[0]) < MIN_WINDOWS \
                and np.count_nonzero(held.inside(segments, 0)) < MIN_SEGMENTS:
            # Too little held out for a comparison: hold every block out once, in turn.
            held = HoldOut.choose(segments, holdout, options.holdout_block, fits,
                                  folds=max(2, int(round(1.0 / holdout))))
    if held is not None:
        folds = []
        for f in range(len(held.folds)):
            test = segments.select(held.inside(segments, f))
            windows, total = scored(held.windows(recordings, window, f))
            windows_total += total
            folds.append((segments.select(held.outside(segments, f)), test, windows))
        for name in options.compare:
            evaluations.append(_evaluate(name, track_width, scales, folds, start_of, settings))
    return held, evaluations, windows_total


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
