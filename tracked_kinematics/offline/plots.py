"""
The picture of an identification: paths like Martinez et al. (2005) Figs. 9-12, and residuals.

Left: the ground-truth path of the longest recording next to dead reckoning from its first
pose through ideal differential drive and through the fitted models. Right: distributions
of the final position and heading errors of the held-out segments (or of all segments when
nothing was held out), ideal drive against the fitted model. Drawn on a plain
matplotlib Figure, so the file is rendered by Agg without touching pyplot state.
"""

from __future__ import annotations

import math
import os

from matplotlib.backend_bases import get_registered_canvas_class
from matplotlib.figure import Figure
import numpy as np
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.models import IdealDiffDrive
from tracked_kinematics.offline.errors import UsageError

_COLOURS = {'ground truth': 'black', 'ideal': 'tab:red', 'written ICR model': 'tab:blue',
            'fitted': 'tab:green'}


def save(fig: Figure, path, dpi: int) -> None:
    """
    Write a figure to ``path``, in the format its extension names.

    Raises
    ------
    UsageError
        When matplotlib cannot write that format (its own message).

    """
    fmt = os.path.splitext(os.fspath(path))[1][1:].lower()
    if fmt and get_registered_canvas_class(fmt) is None:
        raise UsageError(f'Format {fmt!r} is not supported (supported formats: '
                         f'{", ".join(sorted(fig.canvas.get_supported_filetypes()))})')
    fig.savefig(path, dpi=dpi)


def _errors(result, recordings, model, p):
    """Per-segment final errors on the held-out (else all) segments."""
    segments = ident.build_segments(recordings, result.segment_length)
    segments = segments.select(segments.travel >= 0.01)
    if result.holdout is not None:
        segments = segments.select(result.holdout.inside(segments))
    return ident.prediction_errors(model, p, segments)


def plot_identification(path, recordings, result) -> None:
    """
    Write the PNG of an :class:`~tracked_kinematics.core.identify.Identification`.

    Parameters
    ----------
    path : path-like
        PNG to write.
    recordings : sequence of Recording
        The data the identification used.
    result : Identification
        Its result.

    """
    track_width = result.icr.track_width
    ideal = IdealDiffDrive(track_width)
    icr_model = ident.build_model('icr_scales', track_width)
    p_icr = icr_model.from_icr(result.icr)
    fitted = result.fit
    candidates = [('ideal', ideal, ideal.initial()),
                  (f'written ICR model ({result.icr_source})', icr_model, p_icr)]
    if fitted.icr is None:
        candidates.append((f'fitted ({fitted.model.name})', fitted.model, fitted.p))

    fig = Figure(figsize=(13, 6.5), layout='constrained')
    grid = fig.add_gridspec(2, 2, width_ratios=(1.5, 1))
    ax_path = fig.add_subplot(grid[:, 0])
    longest = max(range(len(recordings)), key=lambda i: recordings[i].duration)
    rec = recordings[longest]
    ax_path.plot(rec.gt_x, rec.gt_y, color='black', lw=3.5, alpha=0.45, label='ground truth')
    ax_path.plot(rec.gt_x[:1], rec.gt_y[:1], 'ko')
    for label, model, p in candidates:
        _, x, y, _ = ident.dead_reckoning(model, p, rec)
        key = label.split(' (')[0]
        ax_path.plot(x, y, lw=1.2, color=_COLOURS.get(key), label=f'{label} odometry')
    ax_path.set_aspect('equal', adjustable='datalim')
    ax_path.set_xlabel('x (m)')
    ax_path.set_ylabel('y (m)')
    ax_path.set_title(f'Dead reckoning over {rec.duration:.0f} s of {rec.name or "recording"}',
                      fontsize=10)
    ax_path.grid(alpha=0.3)
    ax_path.legend(loc='best', fontsize=8)

    ax_pos = fig.add_subplot(grid[0, 1])
    ax_head = fig.add_subplot(grid[1, 1])
    errors = [(label, *_errors(result, recordings, model, p)) for label, model, p in candidates]
    top_pos = max(float(np.percentile(e[1], 99)) if len(e[1]) else 0.0 for e in errors) or 1e-3
    top_head = max(float(np.percentile(e[2], 99)) if len(e[2]) else 0.0 for e in errors) or 1e-3
    for label, pos, head in errors:
        key = label.split(' (')[0]
        colour = _COLOURS.get(key)
        ax_pos.hist(1000 * pos, bins=np.linspace(0, 1000 * top_pos, 40), histtype='step',
                    lw=1.5, color=colour, label=f'{label}: mean {1000 * pos.mean():.1f} mm')
        ax_head.hist(np.degrees(head), bins=np.linspace(0, math.degrees(top_head), 40),
                     histtype='step', lw=1.5, color=colour,
                     label=f'{label}: mean {math.degrees(head.mean()):.2f} deg')
    which = 'held-out' if result.holdout is not None else 'all'
    seg = f'{result.segment_length:g} s' if result.segment_length else 'ground-truth period'
    ax_pos.set_title(f'Final position error of {which} segments ({seg})', fontsize=10)
    ax_pos.set_xlabel('mm')
    ax_head.set_title(f'Final heading error of {which} segments', fontsize=10)
    ax_head.set_xlabel('deg')
    for ax in (ax_pos, ax_head):
        ax.set_ylabel('segments')
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    icr = result.icr
    fig.suptitle(f'identify_icr: {fitted.model.name} ({fitted.method}); chi = {icr.chi:.3f}, '
                 f'e = {icr.eccentricity:.3f}', fontsize=12)
    save(fig, path, dpi=110)
