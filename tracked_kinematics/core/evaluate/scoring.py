"""
The whole evaluation of terrain models on recordings, as one dictionary per model.

:func:`evaluate` cuts the recordings into pieces, dead-reckons each model and scores it: windows,
evo's RPE, horizons from the encoders and predictions from the commands. The keys are the public
contract of evaluate_model's report (docs/tools/evaluate_model.md).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .horizons import command_horizons, Commands, encoder_horizons, HorizonErrors
from .metrics import relative_errors, rpe, summary
from .pieces import cut, moving_windows, odometry, Piece, track_path
from ..drivetrain import DriveTrain
from ..identify import Recording
from ..kinematics import IcrParams


@dataclass(frozen=True)
class Settings:
    """
    What to score: ``windows`` and ``horizon`` (s), ``rpe_deltas`` (m), command ``dt`` and age (s).

    ``jumps`` cuts the data at ground-truth jumps too (``track_width`` m for heading glitches);
    ``min_speed`` (m/s) scores only windows whose mean track speed reaches it (None: all).
    """

    windows: tuple = (5.0, 10.0)
    horizon: float = 2.0
    dt: float = 0.05
    rpe_deltas: tuple = (1.0, 10.0)
    max_command_age: float = 0.5
    jumps: bool = True
    track_width: float | None = None
    min_speed: float | None = None


@dataclass(frozen=True)
class Data:
    """One recording to score on (ground-truth delay taken off), with its commands or None."""

    recording: Recording
    commands: Commands | None = None


@dataclass(frozen=True)
class Candidate:
    """
    A model to score: report ``name``, ``icr``, and the ``drivetrain`` of its command predictions.

    ``runs`` (the online estimator's replay of each recording) replace ``icr``'s ICRs over time;
    ``tracks`` (per recording, a path ``(t, poses)`` computed elsewhere, such as the gyro-aided
    odometry of :func:`.gyro.gyro_tracks`) replace the odometry of the pieces (each path
    re-anchored at the piece's first ground-truth pose); the horizons and the predictions
    remain ``icr``'s.
    """

    name: str
    icr: IcrParams
    drivetrain: DriveTrain | None = None
    runs: tuple | None = None
    tracks: tuple | None = None

    def params_at(self, recording: int):
        """Return ``times -> (y_left, y_right, x, scale_left, scale_right)`` for a recording."""
        if self.runs is not None:
            return self.runs[recording].params_at
        icr = self.icr
        values = (icr.y_left, icr.y_right, icr.x, icr.scale_left, icr.scale_right)
        return lambda times: values


def _number(value):
    """Return a JSON number: a float, or None for NaN."""
    value = float(value)
    return value if math.isfinite(value) else None


def _mean(values):
    return _number(np.mean(values)) if len(values) else None


def _p90(values):
    return _number(np.percentile(values, 90)) if len(values) else None


def _horizon_summary(errors: HorizonErrors) -> dict:
    return {'n': len(errors),
            'mean_rmse_translation_m': _mean(errors.rms_translation),
            'mean_rmse_rotation_rad': _mean(errors.rms_rotation),
            'p90_rmse_translation_m': _p90(errors.rms_translation),
            'p90_rmse_rotation_rad': _p90(errors.rms_rotation),
            'mean_final_translation_m': _mean(errors.final_translation),
            'mean_final_rotation_rad': _mean(errors.final_rotation)}


def _window_summary(position, heading, distance, total) -> dict:
    travelled = float(np.sum(distance))
    return {'n': int(len(position)), 'n_total': int(total),
            'mean_position_error_m': _mean(position), 'p90_position_error_m': _p90(position),
            'mean_heading_error_rad': _mean(heading), 'p90_heading_error_rad': _p90(heading),
            'mean_distance_m': _mean(distance),
            'drift_pct': _number(100.0 * np.sum(position) / travelled) if travelled > 0
            else None}


def window_key(seconds: float) -> str:
    """Key of a window length in the report: ``5`` for 5 s, ``2.5`` for 2.5 s."""
    return f'{float(seconds):g}'


def rpe_key(delta: float) -> str:
    """Key of an RPE distance in the report: ``1m``, ``10m``, ``0.5m``."""
    return f'{float(delta):g}m'


@dataclass
class _Scores:
    """Errors of one model, pooled over the pieces."""

    windows: dict
    rpe: dict
    horizons: list
    predictions: list
    paths: list


def _score(candidate: Candidate, pieces, data, settings: Settings) -> _Scores:
    scores = _Scores({w: ([], [], [], []) for w in settings.windows},
                     {d: ([], [], [], []) for d in settings.rpe_deltas}, [], [], [])
    for piece in pieces:
        params_at = candidate.params_at(piece.recording)
        if candidate.runs is None:
            step_params = params_at(None)
        else:
            step_params = params_at(piece.grid[:-1])
        if candidate.tracks is None:
            path = odometry(piece, step_params)
        else:
            path = track_path(piece, *candidate.tracks[piece.recording])
        scores.paths.append(path)
        walked = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(piece.truth[:, 0]),
                                                           np.diff(piece.truth[:, 1])))])
        for length, (position, heading, distance, total) in scores.windows.items():
            i, j, n = moving_windows(piece, length, settings.min_speed)
            total.append(n)
            p, h = relative_errors(path, piece.truth, i, j)
            position.append(p)
            heading.append(h)
            distance.append(walked[j] - walked[i])
        for delta, errors in scores.rpe.items():
            for k, from_reference in ((0, False), (2, True)):
                tr, rot = rpe(path, piece.truth, delta, from_reference)
                errors[k].append(tr)
                errors[k + 1].append(rot)
        scores.horizons.append(encoder_horizons(piece, settings.horizon, params_at))
        commands = data[piece.recording].commands
        if commands is not None:
            scores.predictions.append(command_horizons(
                piece, settings.horizon, commands, params_at, candidate.drivetrain,
                settings.dt, settings.max_command_age))
    return scores


def _report(candidate: Candidate, scores: _Scores, settings: Settings, commands) -> dict:
    windows = {window_key(w): _window_summary(*(np.concatenate(parts) if parts else np.zeros(0)
                                                for parts in values[:3]), sum(values[3]))
               for w, values in scores.windows.items()}
    longest = window_key(max(settings.windows)) if settings.windows else None
    entry = {
        'odometry': {
            'windows': windows,
            'drift_pct': windows[longest]['drift_pct'] if longest else None,
            'horizon': {'horizon_s': settings.horizon,
                        **_horizon_summary(HorizonErrors.concatenate(scores.horizons))},
        },
        'rpe': {},
    }

    def pooled(parts):
        return np.concatenate(parts) if parts else np.zeros(0)

    for delta, (translation, rotation, ref_translation, ref_rotation) in scores.rpe.items():
        per_piece = [{'piece': k, 'pairs': len(errors), 'rmse': summary(errors)['rmse'],
                      'mean': summary(errors)['mean']}
                     for k, errors in enumerate(translation) if len(errors)]
        key = rpe_key(delta)
        stats = summary(pooled(translation))
        entry[f'rpe_{key}'] = stats['rmse']
        entry[f'rpe_{key}_mean'] = stats['mean']
        same = summary(pooled(ref_translation))
        entry['rpe'][key] = {'delta_m': float(delta), 'pairs': stats['n'],
                             'translation_m': stats, 'rotation_rad': summary(pooled(rotation)),
                             'pieces': per_piece,
                             'pairs_from_reference': {
                                 'pairs': same['n'], 'translation_m': same,
                                 'rotation_rad': summary(pooled(ref_rotation))}}
    if commands:
        entry['prediction'] = {
            'source': commands, 'horizon_s': settings.horizon, 'dt_s': settings.dt,
            'drivetrain': 'none: commands taken as track speeds' if candidate.drivetrain
            is None else "the model file's",
            **_horizon_summary(HorizonErrors.concatenate(scores.predictions))}
    else:
        entry['prediction'] = None
    return entry


@dataclass(frozen=True)
class Evaluation:
    """Result of :func:`evaluate`: report entry per model, the pieces and cuts, odometry paths."""

    models: dict
    pieces: list
    cuts: list
    paths: dict


def evaluate(data, candidates, settings: Settings | None = None) -> Evaluation:
    """Score every candidate (in report order) on every recording."""
    settings = settings or Settings()
    cuts = [cut(d.recording, index, settings.jumps, settings.track_width)
            for index, d in enumerate(data)]
    pieces: list[Piece] = [p for c in cuts for p in c.pieces]
    sources = sorted({d.commands.source for d in data if d.commands is not None})
    commands = ', '.join(sources) if sources else None
    models, paths = {}, {}
    for candidate in candidates:
        scores = _score(candidate, pieces, data, settings)
        models[candidate.name] = _report(candidate, scores, settings, commands)
        paths[candidate.name] = scores.paths
    return Evaluation(models, pieces, cuts, paths)
