"""
evaluate_model's report as a library: terrain models scored on recordings.

The command line (:mod:`tracked_kinematics.offline.cli.evaluate_model`) parses, reads the
bags, prints, writes and plots; the report's keys are in docs/tools/evaluate_model.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime, timezone
import json
import math
from pathlib import Path

import numpy as np
from tracked_kinematics.core import evaluate as ev
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.errors import ExcitationError, InvalidParameters
from tracked_kinematics.core.estimate.config import EstimatorConfig
from tracked_kinematics.core.evaluate.consistency import (
    gyro_track, gyro_window_consistency, window_consistency)
from tracked_kinematics.core.evaluate.gyro_noise import GYRO_TERMS
from tracked_kinematics.core.evaluate.verdict import MIN_WINDOWS
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.noise_model import TERMS
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.tooling import json_ready
from tracked_kinematics.params import (
    drivetrain_from_values, gyro_config_from_values, gyro_noise_model_from_values,
    icr_from_values, noise_model_from_values, read_params_file, track_noise_from_values,
    values_from_drivetrain)

TOOL = 'evaluate_model'
CLOSE = 0.05
"""Rows whose error is within 5 % of the best row's are named beside it."""


# Inputs ----------------------------------------------------------------------------------


class TerrainModel:
    """
    One terrain file: its ``values`` (ICRs defaulted), ``icr``, ``drivetrain`` and report ``name``.

    ``drivetrain_in_file`` says whether the file has ``drivetrain.*`` keys. Raises
    InvalidParameters (prefixed with the path) or OSError.
    """

    def __init__(self, path):
        self.path = str(path)
        self.values = read_params_file(path)
        # docs/model.md: the tread ICRs default to +-track_width/2 (ideal drive for the
        # file's width) unless set.
        width = self.values.get('track_width')
        if isinstance(width, (int, float)) and not isinstance(width, bool):
            self.values.setdefault('icr.y_left', 0.5 * width)
            self.values.setdefault('icr.y_right', -0.5 * width)
        try:
            self.icr = icr_from_values(self.values)
            self.drivetrain = drivetrain_from_values(self.values)
        except InvalidParameters as err:
            raise InvalidParameters(f'{path}: {err}') from None
        self.drivetrain_in_file = any(k.startswith('drivetrain.') for k in self.values)
        self.name = Path(path).stem
        # As odometry_node reads them, checked by its table.
        try:
            self.noise = noise_model_from_values(self.values)
            self.gyro_noise = gyro_noise_model_from_values(self.values)
            self.gyro = gyro_config_from_values(self.values)
        except ValueError as err:
            raise InvalidParameters(f'{path}: {err}') from None


def estimator_config_of(values) -> EstimatorConfig:
    """
    Return icr_estimator's EKF settings for a terrain file: its defaults, the file's noise model.

    As the node reads them: ``covariance.k_left``/``k_right`` (averaged), ``covariance.turn``
    and ``covariance.slip`` where the file has them, else 0 (the EKF's ``travel_std`` alone).
    """
    def value(key):
        found = values.get(key, 0.0)
        return 0.0 if isinstance(found, bool) or not isinstance(found, (int, float)) \
            else float(found)
    return EstimatorConfig(
        track_noise=0.5 * (value('covariance.k_left') + value('covariance.k_right')),
        turn_noise=value('covariance.turn'), slip_noise=value('covariance.slip'))


def read_terrain_models(paths) -> list[TerrainModel]:
    """Read terrain files, each named by its unique stem (``a``, ``a_2``; never ``ideal``)."""
    models = [TerrainModel(path) for path in paths]
    taken = {'ideal'}
    for model in models:
        name, n = model.name, 2
        while name in taken or f'online_{name}' in taken:
            name, n = f'{model.name}_{n}', n + 1
        model.name = name
        taken |= {name, f'online_{name}'}
    return models


@dataclass(frozen=True)
class References:
    """
    The recordings to score on (``data``), their ``records``, delay ``account``, ``reference``.

    ``reference`` is ``'pose'`` (ground truth) or ``'imu'`` (the gyro: heading only).
    """

    data: tuple
    records: tuple
    account: str
    reference: str = 'pose'


def _delays(recordings, delay):
    """Return the ground-truth delay of each recording and a one-line account, as identify_icr."""
    if delay != 'auto':
        given = ident.fixed_delay(delay)
        return [given] * len(recordings), f'{given.delay:g} s (given)'
    pooled, each = ident.estimate_delays(recordings)
    if not pooled.determined:
        return [pooled] * len(recordings), (f'{pooled.describe()}; none removed: give it '
                                            'with --ground-truth-delay')
    if each:
        return each, 'per bag: ' + '; '.join(e.describe() for e in each)
    return [pooled] * len(recordings), pooled.describe()


def pose_references(bags, found, delay='auto') -> References:
    """
    Take the ground-truth delay off recordings read with a pose as the reference.

    Parameters
    ----------
    bags : sequence of path-like
        The bags, for the records.
    found : sequence of (Recording, tuple or None)
        Each bag's recording (:func:`tracked_kinematics.offline.bags.read_recording`) and
        its commands (:func:`commands_of`).
    delay : 'auto' or float
        The ground-truth delay behind the encoders, s; ``'auto'`` estimates it.

    """
    recordings = [recording for recording, _ in found]
    delays, account = _delays(recordings, delay)
    data, records = [], []
    for bag, (recording, cmds), delay in zip(bags, found, delays):
        if cmds is not None:
            cmds = ev.Commands(*cmds)
        data.append(ev.Data(ident.correct_ground_truth([recording], delay.delay)[0], cmds))
        records.append({
            'bag': str(Path(bag).resolve()), 'name': Path(bag).name,
            'duration_s': recording.duration, 'encoder_samples': len(recording.enc_t),
            'ground_truth_samples': len(recording.gt_t),
            'ground_truth_delay_s': float(delay.delay),
            'ground_truth_delay_std_s': None if delay.uncertainty == 'given'
            else float(delay.std),
            'ground_truth_delay_source': 'given' if delay.uncertainty == 'given'
            else ('auto' if delay.determined else 'not determined'),
            'commands': None if cmds is None else cmds.source,
            'command_samples': 0 if cmds is None else len(cmds.t)})
    return References(tuple(data), tuple(records), account)


def gyro_references(bags, found, track_width: float, imu_delay='auto') -> References:
    """
    Make the gyro of each recording a heading-only reference: its bias and delay removed.

    ``found`` are the recordings read with the gyro
    (:func:`tracked_kinematics.offline.bags.read_recording`); ``track_width`` (m) is the
    ideal drive the gyro fit starts from; ``imu_delay`` the gyro's delay behind the encoders
    (s), or ``'auto'`` to estimate it as identify_icr does, by the same rule
    (:func:`tracked_kinematics.core.identify.reference.delays.imu_delay_problem`): a delay
    the slipping tracks cannot time is refused, not scored with. Raises ExcitationError when
    the drives cannot time and de-bias the gyro.
    """
    try:
        gyro = ident.fit_recordings(found, track_width, imu_delay=imu_delay,
                                    strict_imu_delay=True)
    except ExcitationError as err:
        if str(err).startswith('the gyro cannot be timed'):
            raise
        raise ExcitationError(f'the gyro cannot be timed and de-biased: {err}') from None
    delay = gyro.imu_delay
    data, records = [], []
    for bag, rec, bias in zip(bags, found, gyro.biases):
        reference = ident.heading_reference(rec, delay.delay, bias)
        data.append(ev.Data(reference, None))
        records.append({
            'bag': str(Path(bag).resolve()), 'name': Path(bag).name,
            'duration_s': reference.duration, 'encoder_samples': len(rec.enc_t),
            'ground_truth_samples': 0, 'gyro_samples': len(rec.gyro_t),
            'gyro_bias_rad_s': float(bias), 'imu_delay_s': float(delay.delay),
            'ground_truth_delay_s': None, 'ground_truth_delay_std_s': None,
            'ground_truth_delay_source': None, 'commands': None, 'command_samples': 0})
    account = f'none (gyro reference); the gyro: {delay.describe()}'
    return References(tuple(data), tuple(records), account, 'imu')


def commands_of(recording):
    """
    Return the commands of a recording as evaluate_model scores them, or None.

    ``(t, values, kind)``: times (s), ``(N, 2)`` nominal track commands (m/s) held until the
    next, and ``'cmd_vel'`` when they came from cmd_vel (the recording has its twists), else
    ``'setpoints'``.
    """
    if recording.command_t is None:
        return None
    kind = 'setpoints' if recording.cmd_vel_t is None else 'cmd_vel'
    return recording.command_t, recording.commands, kind


def check_gyro_rate(bag, recording, topic: str) -> None:
    """
    Refuse a recording whose gyro has no rate, for evaluate_model's ``--fuse-imu``.

    Raises UsageError when the topic carries an orientation only.
    """
    if recording.gyro_rate is None:
        raise UsageError(f'--fuse-imu {topic}: {bag} has no angular velocity on it (an '
                         'orientation only): the gyro-aided odometry needs the rate')


# The report ------------------------------------------------------------------------------


@dataclass(frozen=True)
class EvaluationReport:
    """The report: its JSON ``content``, its :meth:`table` and the ``evaluation`` scored."""

    content: dict
    evaluation: ev.Evaluation
    normalised: dict = field(default_factory=dict)
    """Per model and window length (s): the normalised position errors (W, 2), for the plot."""

    @property
    def names(self) -> list:
        """Return the models in report order: ``ideal``, the files, the online estimators."""
        return list(self.content['order'])

    def json(self) -> str:
        """Return the report as JSON text (no NaN), ending in a newline."""
        return json.dumps(self.content, indent=2, allow_nan=False) + '\n'

    def table(self) -> str:
        """Return the summary evaluate_model prints (:func:`table_text`)."""
        return table_text(self.content)


def evaluate_models(references: References, models, settings: ev.Settings, *,
                    sprocket_radius: float, command_source: str = 'auto',
                    online: bool = False, fuse_imu: bool = False) -> EvaluationReport:
    """
    Score the ideal drive and each terrain model on the recordings; return the report.

    Parameters
    ----------
    references : References
        The recordings (:func:`pose_references`, :func:`gyro_references`).
    models : sequence of TerrainModel
        The terrain files, after the ideal drive of ``settings.track_width``.
    settings : Settings
        What to score.
    sprocket_radius : float
        m, the radius the encoders were read with (recorded in the report).
    command_source : str
        How the commands were read (recorded in the report).
    online : bool
        Also replay the icr_estimator's EKF from each file (``online_`` entries; pose only).
    fuse_imu : bool or str
        Also score each file gyro-aided (``<name>+imu`` entries, after the file's): the
        recordings carry a gyro (``gyro_t``, ``gyro_rate``); pose only. A string is the
        gyro's topic, for the report's ``settings.fuse_imu_topic`` and the closing advice.

    Raises
    ------
    ExcitationError
        When no stretch has both encoders and a reference without a gap.
    ValueError
        For ``online`` or ``fuse_imu`` with a gyro reference.

    """
    if (online or fuse_imu) and references.reference != 'pose':
        raise ValueError('the online estimator and the gyro-aided odometry need a pose '
                         'reference, not the gyro')
    track_width = settings.track_width
    candidates = [ev.Candidate('ideal', IcrParams.ideal(track_width), None)]
    runs = {}
    for m in models:
        candidates.append(ev.Candidate(m.name, m.icr, m.drivetrain))
        if fuse_imu:
            replays = [gyro_track(d.recording, m.icr, m.gyro, m.noise) for d in references.data]
            runs[f'{m.name}+imu'] = replays
            candidates.append(ev.Candidate(f'{m.name}+imu', m.icr, m.drivetrain,
                                           tracks=tuple((t, p) for t, p, _ in replays)))
    if online:
        for m in models:
            runs[m.name] = tuple(ev.replay(d.recording, m.icr, r['ground_truth_delay_s'],
                                           estimator_config_of(m.values))
                                 for d, r in zip(references.data, references.records))
            candidates.append(ev.Candidate(f'online_{m.name}', m.icr, m.drivetrain,
                                           runs[m.name]))
    evaluation = ev.evaluate(references.data, candidates, settings)
    if not evaluation.pieces:
        raise ExcitationError('no stretch of the bags has both encoders and ground truth '
                              'without a gap: nothing to score')
    normalised = {}
    if references.reference == 'pose':
        normalised = _consistency(evaluation, models, candidates, settings,
                                  [d.recording for d in references.data])
    content = json_ready(_content(references, models, evaluation, candidates, runs, settings,
                                  sprocket_radius, command_source))
    content['settings']['fuse_imu_topic'] = fuse_imu if isinstance(fuse_imu, str) else None
    if references.reference == 'imu':
        content = _heading_only(content)
    return EvaluationReport(content, evaluation, normalised)


def _consistency(evaluation, models, candidates, settings, recordings) -> dict:
    """
    Add ``odometry.windows.<s>.consistency`` to each file's entries (and its ``+imu``'s).

    A ``+imu`` entry scores the covariance the gyro-aided odometry_node publishes, computed
    by the node's code (:func:`gyro_window_consistency`: reset every window). Returns the
    normalised errors per model and window length for the plot.
    """
    by_name = {m.name: m for m in models}
    out = {}
    for c in candidates:
        gyro = c.name.endswith('+imu') and c.tracks is not None
        model = by_name.get(c.name[:-len('+imu')] if gyro else c.name)
        if model is None or c.runs is not None:
            continue
        if gyro:
            found = gyro_window_consistency(recordings, evaluation.pieces, c.icr, model.gyro,
                                            track_noise_from_values(model.values), model.noise,
                                            settings.windows, settings.min_speed,
                                            model.gyro_noise)
        else:
            found = window_consistency(evaluation.pieces, evaluation.paths[c.name], c.icr,
                                       model.noise, settings.windows, settings.min_speed)
        windows = evaluation.models[c.name]['odometry']['windows']
        for length, result in found.items():
            windows[ev.window_key(length)]['consistency'] = result['consistency']
        out[c.name] = {length: result['normalised'] for length, result in found.items()}
    return out


def _icr_summary(icr: IcrParams) -> dict:
    return {'track_width': icr.track_width, 'y_left': icr.y_left, 'y_right': icr.y_right,
            'x': icr.x, 'scale_left': icr.scale_left, 'scale_right': icr.scale_right,
            'chi': icr.chi, 'eccentricity': icr.eccentricity}


def _model_entry(candidate, by_name, runs) -> dict:
    """Return a candidate's report entry before its scores: kind, file, ICRs, drivetrain."""
    if candidate.name == 'ideal':
        return {'kind': 'ideal', 'file': None, 'icr': _icr_summary(candidate.icr),
                'drivetrain': None}
    online = candidate.runs is not None
    gyro = candidate.tracks is not None
    model = by_name[candidate.name[len('online_'):] if online
                    else candidate.name[:-len('+imu')] if gyro else candidate.name]
    entry = {'kind': 'online' if online else 'gyro' if gyro else 'file',
             'file': str(Path(model.path).resolve()),
             'icr': _icr_summary(model.icr),
             'drivetrain': {**values_from_drivetrain(model.drivetrain),
                            'from_file': model.drivetrain_in_file}}
    if online:
        rs = runs[model.name]
        outcomes = {}
        for r in rs:
            for k, v in r.outcomes.items():
                outcomes[k] = outcomes.get(k, 0) + v
        entry['online'] = {
            'model': 'icr', 'start': model.name, 'outcomes': outcomes,
            'noise_scale': float(max(r.noise_scale for r in rs)),
            'trusted_fraction': float(np.mean([r.trusted for r in rs])),
            'final_icr': [r.icr[-1].tolist() for r in rs]}
    if gyro:
        odos = [odo for _, _, odo in runs[candidate.name]]
        entry['gyro'] = {
            'imu_delay_s': model.gyro.imu_delay, 'gyro_scale': model.gyro.gyro_scale,
            'bias_rad_s': [o.bias for o in odos],
            'noise_rad_per_sqrt_s': [o.gyro_noise for o in odos],
            'switches': [o.switches for o in odos],
            'source_at_end': [o.source for o in odos],
            'from_file': {k: k in model.values for k in ('imu_delay', 'gyro_scale')},
            'noise': {**{t: getattr(model.gyro_noise, t) for t in GYRO_TERMS},
                      'from_file': any(k.startswith('covariance.gyro_aided.')
                                       for k in model.values)}}
    elif candidate.name != 'ideal' and not online:
        entry['noise'] = {**{t: getattr(model.noise, t) for t in TERMS},
                          'from_file': any(k.startswith('covariance.') for k in model.values)}
    return entry


def _content(references, models, evaluation, candidates, runs, settings, radius,
             command_source) -> dict:
    cuts = evaluation.cuts
    records = [{**record, 'pieces': len(c.pieces), 'seconds_in_pieces': c.seconds,
                'gaps': c.gaps, 'jumps': c.jumps}
               for record, c in zip(references.records, cuts)]
    by_name = {m.name: m for m in models}
    entries = {c.name: {**_model_entry(c, by_name, runs), **evaluation.models[c.name]}
               for c in candidates}
    moving = settings.min_speed is not None
    return {
        'tool': TOOL, 'date': datetime.now(timezone.utc).isoformat(timespec='seconds'),
        'bags': [r['bag'] for r in records],
        'settings': {'windows_s': [float(w) for w in settings.windows],
                     'horizon_s': settings.horizon, 'prediction_dt_s': settings.dt,
                     'rpe_distances_m': [float(d) for d in settings.rpe_deltas],
                     'max_command_age_s': settings.max_command_age,
                     'keep_jumps': not settings.jumps,
                     'track_width': settings.track_width, 'sprocket_radius': radius,
                     'command_source': command_source},
        'recordings': records,
        'ground_truth_delay': references.account,
        'windows_selection': {'moving_only': moving,
                              'min_speed_mps': settings.min_speed if moving else None},
        'data': {'pieces': sum(len(c.pieces) for c in cuts), 'gaps': sum(c.gaps for c in cuts),
                 'jumps': sum(c.jumps for c in cuts),
                 'seconds': float(sum(c.seconds for c in cuts))},
        'pieces': [{'piece': k, 'bag': records[p.recording]['bag'], 't_start_s': float(p.t[0]),
                    't_end_s': float(p.t[-1]), 'samples': len(p.t),
                    'path_length_m': p.path_length}
                   for k, p in enumerate(evaluation.pieces)],
        'order': [c.name for c in candidates], 'models': entries,
    }


def _heading_only(report) -> dict:
    """Null every position figure of a report scored against a gyro (they were not measured)."""
    for entry in report['models'].values():
        odo = entry['odometry']
        for win in odo['windows'].values():
            for key in ('mean_position_error_m', 'p90_position_error_m', 'mean_distance_m',
                        'drift_pct'):
                win[key] = None
        odo['drift_pct'] = None
        for key in list(odo['horizon']):
            if 'translation' in key:
                odo['horizon'][key] = None
        for key in list(entry):
            if key.startswith('rpe_'):
                entry[key] = None
        entry['rpe'] = None
        entry['prediction'] = None
    for piece in report['pieces']:
        piece['path_length_m'] = None
    report['reference'] = 'imu'
    report['scored'] = 'heading only: the gyro measures no position'
    return report


# The table -------------------------------------------------------------------------------


def _fmt(value, scale=1.0, digits=3) -> str:
    return '-' if value is None else f'{scale * value:.{digits}f}'


def _table_rows(report, windows, deltas, sources) -> list:
    """Return the table's header line and one line per model."""
    horizon = f'{report["settings"]["horizon_s"]:g} s'
    head = f'{"model":<26}'
    for w in windows:
        head += f'{w + " s: pos m":>13}{"hdg deg":>9}'
    head += f'{"drift %":>9}'
    for d in deltas:
        head += f'{"RPE " + d.replace("m", " m"):>10}'
    head += f'{horizon + " enc: m":>14}{"deg":>7}'
    if sources:
        head += f'{horizon + " cmd: m":>14}{"deg":>7}'
    rows = [head]
    for name, m in report['models'].items():
        odo = m['odometry']
        row = f'{name:<26}'
        for w in windows:
            win = odo['windows'][w]
            row += f'{_fmt(win["mean_position_error_m"]):>13}'
            row += f'{_fmt(win["mean_heading_error_rad"], 180 / math.pi, 2):>9}'
        row += f'{_fmt(odo["drift_pct"], digits=1):>9}'
        for d in deltas:
            row += f'{_fmt(m[f"rpe_{d}"]):>10}'
        hor = odo['horizon']
        row += f'{_fmt(hor["mean_rmse_translation_m"]):>14}'
        row += f'{_fmt(hor["mean_rmse_rotation_rad"], 180 / math.pi, 2):>7}'
        if sources:
            pred = m['prediction'] or {}
            row += f'{_fmt(pred.get("mean_rmse_translation_m")):>14}'
            row += f'{_fmt(pred.get("mean_rmse_rotation_rad"), 180 / math.pi, 2):>7}'
        rows.append(row.rstrip())
    return rows


def _consistency_rows(report, windows) -> list:
    """
    Return the consistency block: per file row and window, shares inside, NEES, verdict.

    Empty when no row has a covariance to check (the ideal drive and the online rows have
    none; a gyro reference measures no position).
    """
    checked = [(name, m['odometry']['windows']) for name, m in report['models'].items()
               if any('consistency' in m['odometry']['windows'][w] for w in windows)]
    if not checked:
        return []
    head = f'{"model":<26}'
    for w in windows:
        head += f'{w + " s: 50 %":>13}{"95 %":>6}{"NEES":>6}  {"verdict":<16}'
    rows = ['\npublished covariance: % of the windows inside its 50 % / 95 % ellipses, mean '
            'NEES (2 if consistent), verdict (rule: docs/tools/evaluate_model.md, "The '
            'verdict")', head.rstrip()]
    for name, wins in checked:
        row = f'{name:<26}'
        for w in windows:
            c = wins[w].get('consistency') or {}
            row += f'{_fmt(c.get("inside_50"), 100, 0):>13}{_fmt(c.get("inside_95"), 100, 0):>6}'
            row += f'{_fmt(c.get("mean_nees"), digits=1):>6}  {c.get("verdict") or "-":<16}'
        rows.append(row.rstrip())
    first = checked[0][1]
    counts = ', '.join(f'{(first[w].get("consistency") or {}).get("independent_windows", 0)} '
                       f'of {w} s' for w in windows)
    rows.append(f'independent (non-overlapping) windows behind each verdict: {counts}; '
                f'"-": fewer than {MIN_WINDOWS}')
    return rows


def _best(report, windows):
    """Return the row with the least mean final error after the longest window, its figures."""
    longest = max(windows, key=float)
    heading_only = report.get('reference') == 'imu'
    key = 'mean_heading_error_rad' if heading_only else 'mean_position_error_m'
    scored = []
    for name, m in report['models'].items():
        value = m['odometry']['windows'][longest][key]
        if value is not None:
            scored.append((value, name))
    scored.sort()
    return longest, key, scored


def _run_command(report, name) -> list:
    """Return the lines that run a row of the report on the robot (venv; workspace)."""
    entry = report['models'][name]
    kind = entry['kind']
    if kind == 'ideal':
        settings = report['settings']
        args = (f'-p track_width:={settings["track_width"]:g} '
                f'-p sprocket_radius:={settings["sprocket_radius"]:g}')
        return ['run it (the ideal drive: none of the files improves on it on these bags):',
                f'  odometry_node --ros-args {args}']
    args = f'--params-file {entry["file"]}'
    if kind == 'gyro':
        topic = report['settings'].get('fuse_imu_topic') or 'YOUR_IMU_TOPIC'
        args += f' -p imu_topic:={topic}'
    if kind != 'online':
        return ['run it:', f'  odometry_node --ros-args {args}']
    file_row = name[len('online_'):]
    alone = report['models'][file_row]['odometry']['windows']
    longest = max(alone, key=float)
    return ['run it (the online estimator needs a pose source on the robot):',
            f'  odometry_node --ros-args {args}',
            f'  icr_estimator --ros-args {args} -p pose_topic:=YOUR_POSE_TOPIC '
            '-p push_to:=[odometry_node]',
            f'without a pose source, the file alone ({file_row}: '
            f'{_fmt(alone[longest]["mean_position_error_m"])} m): the first line']


def _advice(report, windows) -> list:
    """Return the closing lines: the row to run, and the command that runs it."""
    longest, key, scored = _best(report, windows)
    if not scored:
        return []
    value, name = scored[0]
    figure = ('mean final heading error', 180 / math.pi, 2, 'deg') \
        if key == 'mean_heading_error_rad' else ('mean final position error', 1.0, 3, 'm')
    what, scale, digits, unit = figure
    others = ', '.join(f'{n} {_fmt(v, scale, digits)}' for v, n in scored[1:4])
    lines = [f'\nbest on these bags ({what} after {longest} s): {name} '
             f'{_fmt(value, scale, digits)} {unit}' + (f' (then {others})' if others else '')
             + '; held-out figures only if the files were fitted on other bags']
    close = [n for v, n in scored[1:] if v <= (1.0 + CLOSE) * value]
    if close:
        lines.append(f'as good within {100 * CLOSE:.0f} % on these bags (one bag more could '
                     f'swap them): {", ".join(close)}')
    verdict = (report['models'][name]['odometry']['windows'][longest].get('consistency')
               or {}).get('verdict')
    if verdict and verdict != 'consistent':
        lines.append(f'its published covariance is {verdict} after {longest} s: see the '
                     'consistency lines above before fusing it')
    return lines + _run_command(report, name) + [
        '(in a ROS 2 workspace: ros2 run tracked_kinematics odometry_node --ros-args ...)']


def table_text(report: dict) -> str:
    """Return the summary of a report that evaluate_model prints (no final newline)."""
    recs = report['recordings']
    cut = report['data']
    settings = report['settings']
    jumps = ('kept' if settings['keep_jumps']
             else f'{cut["jumps"]} ground-truth jumps left out')
    lines = [f'{TOOL}: {len(recs)} bag(s), {sum(r["duration_s"] for r in recs):.0f} s; scored '
             f'{cut["seconds"]:.0f} s in {cut["pieces"]} gap-free pieces ({cut["gaps"]} gaps, '
             f'{jumps})',
             f'ground-truth delay behind the encoders: {report["ground_truth_delay"]}']
    if report.get('reference') == 'imu':
        lines.append('reference: the gyro, heading only: position figures are not scored '
                     '(null in the report, - below)')
    sources = sorted({r['commands'] for r in recs if r['commands']})
    if not sources:
        lines.append('no commands in the bags: no prediction from commands')
    windows = [ev.window_key(w) for w in settings['windows_s']]
    deltas = [ev.rpe_key(d) for d in settings['rpe_distances_m']]
    lines.append(f'\nerrors: window means (p90 and more in the report); RPE: RMSE of the '
                 f'translation part; {settings["horizon_s"]:g} s predictions: mean RMSE over '
                 'the horizon')
    lines += _table_rows(report, windows, deltas, sources)
    ideal = report['models']['ideal']
    counts = ideal['odometry']['windows']
    selection = report['windows_selection']
    if selection['moving_only']:
        line = (f'windows in which the tracks move (mean track speed >= '
                f'{selection["min_speed_mps"]:g} m/s; --all-windows for all): '
                + ', '.join(f'{counts[w]["n"]} of {counts[w]["n_total"]} of {w} s'
                            for w in windows))
    else:
        line = 'windows, idle ones too: ' + ', '.join(f'{counts[w]["n"]} of {w} s'
                                                      for w in windows)
    line += f'; {ideal["odometry"]["horizon"]["n"]} horizons from the encoders'
    if sources:
        line += f', {(ideal["prediction"] or {}).get("n", 0)} from the commands'
    lines.append(line)
    for name, m in report['models'].items():
        online = m.get('online')
        if online:
            outcomes = online['outcomes']
            lines.append(
                f'{name}: {outcomes.get("updated", 0)} updates, {outcomes.get("outlier", 0)} '
                f'poses refused as jumps, {outcomes.get("anchored", 0)} re-anchors; model '
                f'error {math.sqrt(online["noise_scale"]):.1f} x travel_std; its own '
                f'estimate in use {100 * online["trusted_fraction"]:.0f} % of the time '
                "(else the file's values)")
    lines += _consistency_rows(report, windows)
    lines += _advice(report, windows)
    return '\n'.join(lines)
