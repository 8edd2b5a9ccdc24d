"""The picture of evaluate_model: error against window length, and a few paths (Agg, no pyplot)."""

from __future__ import annotations

import math

from matplotlib.backend_bases import get_registered_canvas_class
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
import numpy as np
from tracked_kinematics.core import evaluate as ev
from tracked_kinematics.offline.errors import UsageError


def check_format(path) -> str:
    """Return the image format of a plot path; UsageError when matplotlib lacks it."""
    fmt = str(path).rsplit('.', 1)[-1].lower() if '.' in str(path) else 'png'
    if get_registered_canvas_class(fmt) is None:
        supported = FigureCanvasAgg(Figure()).get_supported_filetypes()
        raise UsageError(f'--plot: format {fmt!r} is not supported (supported formats: '
                         f'{", ".join(sorted(supported))})')
    return fmt


def error_curves(evaluation, names, lengths, min_speed=None):
    """
    Return mean final position (m) and heading (rad) errors per model and window length.

    Over the windows of mean track speed >= ``min_speed`` (m/s; None: all), as the report's.
    """
    curves = {}
    for name in names:
        position, heading = [], []
        for length in lengths:
            p_all, h_all = [], []
            for piece, path in zip(evaluation.pieces, evaluation.paths[name]):
                i, j, _ = ev.moving_windows(piece, length, min_speed)
                p, h = ev.relative_errors(path, piece.truth, i, j)
                p_all.append(p)
                h_all.append(h)
            p_all = np.concatenate(p_all) if p_all else np.zeros(0)
            h_all = np.concatenate(h_all) if h_all else np.zeros(0)
            position.append(p_all.mean() if len(p_all) else math.nan)
            heading.append(h_all.mean() if len(h_all) else math.nan)
        curves[name] = (np.array(position), np.array(heading))
    return curves


def _scale_to_calibrated(ax, lengths, curves, names, windows, unit, digits):
    """
    Fit the y axis to the calibrated models; the ideal drive, far above, is drawn off-scale.

    The ideal drive's errors are often ten times the calibrated models': on one axis every
    calibrated curve would lie flat on zero. Its legend entry states its values at the
    report's windows instead.
    """
    others = [c for name, c in curves.items() if name != 'ideal' and np.isfinite(c).any()]
    if 'ideal' not in names or not others:
        return
    top = 1.25 * max(float(np.nanmax(c)) for c in others)
    ideal = curves['ideal']
    if not np.isfinite(ideal).any() or np.nanmax(ideal) <= top or top <= 0.0:
        return
    ax.set_ylim(0.0, top)
    at = [f'{ideal[np.argmin(abs(lengths - w))]:.{digits}f} {unit} at {w:g} s'
          for w in windows if w <= lengths[-1]]
    for line in ax.get_lines():
        if line.get_label() == 'ideal':
            line.set(ls='--', label='ideal (off scale: ' + ', '.join(at) + ')')


def evaluation_figure(evaluation, names, windows=(5.0, 10.0), paths: int = 3,
                      min_speed=None) -> Figure:
    """
    Return the figure of :func:`plot_evaluation` (the error curves' axes first).

    The error axes fit the calibrated models; the ideal drive, when far above them, runs off
    the top (dashed), its values at the report's windows in its legend entry.
    """
    longest = max((p.duration for p in evaluation.pieces), default=0.0)
    top = max(min(longest, 3.0 * max(windows)), 1.0)
    lengths = np.unique(np.concatenate([np.linspace(top / 15, top, 15),
                                        [w for w in windows if w <= longest]]))
    curves = error_curves(evaluation, names, lengths, min_speed)
    order = sorted(range(len(evaluation.pieces)), key=lambda k: -evaluation.pieces[k].duration)
    shown = order[:paths]
    columns = max(2, len(shown))
    fig = Figure(figsize=(5.0 * columns, 9.0))
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(2, columns)
    top_axes = [fig.add_subplot(grid[0, :columns // 2]), fig.add_subplot(grid[0, columns // 2:])]
    colours = {name: f'C{k}' for k, name in enumerate(names)}
    for name in names:
        position, heading = curves[name]
        top_axes[0].plot(lengths, position, '.-', color=colours[name], label=name)
        top_axes[1].plot(lengths, np.degrees(heading), '.-', color=colours[name], label=name)
    _scale_to_calibrated(top_axes[0], lengths, {n: c[0] for n, c in curves.items()}, names,
                         windows, 'm', 2)
    _scale_to_calibrated(top_axes[1], lengths, {n: np.degrees(c[1]) for n, c in curves.items()},
                         names, windows, 'deg', 1)
    top_axes[0].set(xlabel='window (s)', ylabel='mean final position error (m)',
                    title='odometry: final position error against window length')
    top_axes[1].set(xlabel='window (s)', ylabel='mean final heading error (deg)',
                    title='odometry: final heading error against window length')
    for ax in top_axes:
        for w in windows:
            ax.axvline(w, color='grey', lw=0.8, ls=':')
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    for column, k in enumerate(shown):
        ax = fig.add_subplot(grid[1, column])
        piece = evaluation.pieces[k]
        ax.plot(piece.truth[:, 0], piece.truth[:, 1], color='black', lw=2.0,
                label='ground truth')
        for name in names:
            odometry = evaluation.paths[name][k]
            ax.plot(odometry[:, 0], odometry[:, 1], color=colours[name], lw=1.0, label=name)
        ax.set(xlabel='x (m)', ylabel='y (m)', aspect='equal', adjustable='datalim',
               title=f'bag {piece.recording + 1}, {piece.t[0]:.0f}-{piece.t[-1]:.0f} s')
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def plot_evaluation(path, evaluation, names, windows=(5.0, 10.0), fmt: str = 'png',
                    paths: int = 3, dpi: int = 110, min_speed=None) -> None:
    """
    Draw the mean final errors against window length and the longest pieces' paths.

    Parameters
    ----------
    path : path-like
        Image to write.
    evaluation : Evaluation
        The scores (:func:`tracked_kinematics.core.evaluate.evaluate`).
    names : sequence of str
        Models to draw, in order.
    windows : sequence of float
        The report's windows, marked on the curves.
    fmt : str
        Image format (the path may be a temporary name).
    paths : int
        How many pieces to draw (the longest ones).
    dpi : int
        Resolution.
    min_speed : float or None
        The curves' windows: those with at least this mean track speed, m/s; None: all.

    """
    fig = evaluation_figure(evaluation, names, windows, paths, min_speed)
    fig.savefig(path, format=fmt, dpi=dpi)


def plot_consistency(path, normalised, windows, fmt: str = 'png', dpi: int = 110) -> None:
    """
    Draw the normalised final position errors of each model against their published ellipses.

    One row per model (the terrain files and their ``+imu`` rows), one pair of panels per
    window length: the histogram of the NEES against the chi-square density of 2 degrees of
    freedom (what a consistent covariance gives; its 50 % and 95 % quantiles marked), and
    the normalised errors ``L^-1 e`` with the 50 % and 95 % circles (radii
    ``sqrt(1.386)`` and ``sqrt(5.991)``).

    Parameters
    ----------
    path : path-like
        Image to write.
    normalised : dict
        Per model and window length (s): the normalised errors (W, 2)
        (:attr:`tracked_kinematics.offline.model_evaluation.EvaluationReport.normalised`).
    windows : sequence of float
        The window lengths, s.
    fmt : str
        Image format.
    dpi : int
        Resolution.

    """
    from tracked_kinematics.core.noise_model import CHI2_50, CHI2_95
    names = list(normalised)
    rows, columns = max(1, len(names)), 2 * max(1, len(windows))
    fig = Figure(figsize=(3.6 * columns, 3.4 * rows))
    FigureCanvasAgg(fig)
    theta = np.linspace(0.0, 2.0 * math.pi, 200)
    for r, name in enumerate(names):
        for c, length in enumerate(windows):
            z = normalised[name].get(float(length), np.zeros((0, 2)))
            nees = np.sum(z * z, 1)
            inside = ((f', {100 * np.mean(nees <= CHI2_50):.0f} % / '
                       f'{100 * np.mean(nees <= CHI2_95):.0f} % inside, mean {nees.mean():.1f}')
                      if len(z) else ', no windows')
            ax = fig.add_subplot(rows, columns, r * columns + 2 * c + 1)
            top = max(12.0, float(np.percentile(nees, 95)) if len(z) else 12.0)
            bins = np.linspace(0.0, top, 40)
            ax.hist(np.minimum(nees, top), bins=bins, density=True, color='C0', alpha=0.6,
                    label='NEES of the windows')
            x = np.linspace(0.0, top, 200)
            ax.plot(x, 0.5 * np.exp(-0.5 * x), 'k', lw=1.5, label='chi-square(2)')
            for q in (CHI2_50, CHI2_95):
                ax.axvline(q, color='grey', ls=':', lw=1.0)
            ax.set(xlabel='NEES (last bin: beyond)', ylabel='density',
                   title=f'{name}, {length:g} s{inside}')
            ax.title.set_fontsize(8)
            ax.legend(fontsize=7)
            ax = fig.add_subplot(rows, columns, r * columns + 2 * c + 2)
            ax.plot(z[:, 0], z[:, 1], '.', ms=2, color='C0', alpha=0.4)
            for q, style in ((CHI2_50, '--'), (CHI2_95, '-')):
                ax.plot(math.sqrt(q) * np.cos(theta), math.sqrt(q) * np.sin(theta), 'k',
                        ls=style, lw=1.0)
            lim = max(4.0, min(float(np.percentile(np.abs(z), 98)) if len(z) else 4.0, 20.0))
            ax.set(xlim=(-lim, lim), ylim=(-lim, lim), aspect='equal',
                   xlabel='normalised error, forward', ylabel='normalised error, left',
                   title='inside the 50 % (dashed) and 95 % circles')
            ax.title.set_fontsize(8)
            ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, format=fmt, dpi=dpi)
