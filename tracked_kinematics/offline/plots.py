"""
The pictures of the offline tools, drawn on plain matplotlib Figures with an Agg canvas.

No pyplot: the tools (and scripts or notebooks calling them) keep their matplotlib state.
"""

from __future__ import annotations

import math
import os

from matplotlib.backend_bases import get_registered_canvas_class
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
import numpy as np
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.models import IdealDiffDrive
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.vehicle_file import fixed

_COLOURS = {'ground truth': 'black', 'ideal': 'tab:red', 'written ICR model': 'tab:blue',
            'fitted': 'tab:green', 'tuned diff_drive_controller': 'tab:orange'}


def _figure(**kwargs) -> Figure:
    """Return a new Figure on its own Agg canvas (``kwargs`` go to :class:`Figure`)."""
    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def check_format(flag: str, path) -> None:
    """Check before any work that matplotlib can write ``path``'s format (UsageError)."""
    if path is None:
        return
    fmt = os.path.splitext(os.fspath(path))[1][1:].lower()
    if not fmt:
        raise UsageError(f'{flag} {os.fspath(path)}: give a file name with an extension '
                         '(.png, .pdf, .svg)')
    if get_registered_canvas_class(fmt) is None:
        supported = sorted(FigureCanvasAgg.get_supported_filetypes())
        raise UsageError(f'{flag} {os.fspath(path)}: Format {fmt!r} is not supported '
                         f'(supported formats: {", ".join(supported)})')


def save(fig: Figure, path, dpi: int) -> None:
    """
    Write a figure to ``path`` (a temporary one of :class:`Outputs`) in its extension's format.

    UsageError when matplotlib cannot write that format.
    """
    check_format('plot', path)
    fig.savefig(path, dpi=dpi)


# identify_icr ----------------------------------------------------------------------------


def _errors(result, segments, model, p):
    """Per-segment final errors on the held-out (else all) segments of the fit."""
    if result.holdout is not None:
        segments = segments.select(result.holdout.inside(segments))
    return ident.prediction_errors(model, p, segments)


def plot_identification(path, recordings, result, segments) -> None:
    """
    Draw an identification: dead reckoning against ground truth, residuals, delay profile.

    Paths like Martinez et al. (2005) Figs. 9-12.

    Parameters
    ----------
    path : path-like
        Image to write (PNG).
    recordings : sequence of Recording
        The data the identification used, its ground-truth delay removed (``result.recordings``).
    result : Identification
        Its result (:func:`tracked_kinematics.core.identify.identify`).
    segments : Segments
        The moving segments it fitted; residuals of the held-out ones (or all when none was).

    """
    track_width = result.icr.track_width
    ideal = IdealDiffDrive(track_width)
    icr_model = ident.build_model('icr_scales', track_width)
    p_icr = icr_model.from_icr(result.icr)
    fitted = result.fit
    candidates = [('ideal', ideal, ideal.initial())]
    if getattr(result, 'ddc', None) is not None:
        candidates.append(('tuned diff_drive_controller', result.ddc.model, result.ddc.p))
    candidates.append((f'written ICR model ({result.icr_source})', icr_model, p_icr))
    if fitted.icr is None:
        candidates.append((f'fitted ({fitted.model.name})', fitted.model, fitted.p))

    fig = _figure(figsize=(13, 9), layout='constrained')
    grid = fig.add_gridspec(3, 2, width_ratios=(1.5, 1))
    ax_path = fig.add_subplot(grid[:, 0])
    _plot_delay(fig.add_subplot(grid[2, 1]), result)
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
    errors = [(label, *_errors(result, segments, model, p)) for label, model, p in candidates]
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


def _plot_delay(ax, result) -> None:
    """Profile cost of the ground-truth delay, with the estimate and its standard error."""
    delay = getattr(result, 'delay', None)
    ax.set_title('Ground-truth delay behind the encoders', fontsize=10)
    ax.set_xlabel('delay (s)')
    if delay is None or not len(delay.cost):
        given = f'{delay.delay:.3f} s' if delay and delay.delay else 'none'
        ax.text(0.5, 0.5, f'given: {given}', ha='center', va='center', transform=ax.transAxes)
        ax.set_yticks([])
        return
    ax.plot(delay.shifts, delay.cost - np.min(delay.cost), color='C0',
            label='profile cost (lower: better timed)')
    if delay.determined:
        ax.axvline(delay.delay, color='C3', ls='--',
                   label=f'{delay.delay:.3f} s +- {delay.std:.3f} ({delay.uncertainty})')
        if np.isfinite(delay.std) and delay.std > 0:
            ax.axvspan(delay.delay - delay.std, delay.delay + delay.std, color='C3', alpha=0.15)
    else:
        ax.text(0.5, 0.9, f'not determined: {delay.problem}', ha='center', va='top',
                transform=ax.transAxes, fontsize=8, wrap=True)
    for e in getattr(result, 'delays', []):
        ax.axvline(e.delay, color='0.5', lw=0.8, ls=':')
    ax.set_ylabel('cost')
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


# identify_drivetrain ---------------------------------------------------------------------


def plot_drivetrain(path, result) -> None:
    """Draw a drive-train fit: 20 s of track speeds, and the delay profile."""
    segment = max(result.segments, key=lambda s: len(s.t))
    simulated = result.simulate(segment)
    # Show the 20 s with the most command activity.
    n = len(segment.t)
    width = min(n, int(round(20.0 / result.dt)))
    activity = np.abs(np.diff(segment.commands, axis=0)).sum(axis=1)
    window = np.convolve(activity, np.ones(width), mode='valid') if n > width else [0.0]
    a = int(np.argmax(window))
    span = slice(a, a + width)
    fig = _figure(figsize=(10, 9), layout='constrained')
    axes = fig.subplots(3, 1)
    for ax, j, side in ((axes[0], 0, 'left'), (axes[1], 1, 'right')):
        t = segment.t[span]
        ax.step(t, segment.commands[span, j], where='post', color='0.6', label='commanded')
        ax.plot(t, segment.speeds[span, j], color='C0', label='measured')
        ax.plot(t, simulated[span, j], color='C3', ls='--', label='model')
        ax.set_ylabel(f'{side} track speed (m/s)')
        ax.legend(loc='upper right')
    axes[1].set_xlabel('time (s)')
    delays, rms = result.delay_profile
    axes[2].plot(delays, 1000 * rms, color='C0')
    axes[2].axvline(result.parameters['delay'], color='C3', ls='--', label='fitted delay')
    axes[2].set_xlabel('command delay (s)')
    axes[2].set_ylabel('rms error (mm/s)')
    axes[2].legend(loc='upper right')
    fig.suptitle(f'identify_drivetrain: {result.loop}, rms {1000 * result.rms:.1f} mm/s')
    save(fig, path, dpi=100)


# icr_map ---------------------------------------------------------------------------------


def plot_icr_map(path, spec, the_map, icr) -> None:
    """
    Plot the map: tread ICRs seen from above, and their dependence on the speed pair.

    Left: each pair's ICRs in base_link, front up (Martinez Figs. 6-7), with the contact patches,
    centre of mass and averaged model ``icr``. Right: ICR coordinates against the direction of
    the speed pair, coloured by its magnitude.
    """
    from matplotlib.patches import Rectangle

    veh = spec.robot.vehicle
    valid = the_map.valid
    fig = _figure(figsize=(13, 6))
    top, side = fig.subplots(1, 2, gridspec_kw={'width_ratios': [1, 1.3]})
    half, length, width = 0.5 * veh.track_width, veh.contact_length, veh.contact_width
    for y_c in (half, -half):
        top.add_patch(Rectangle((y_c - 0.5 * width, -0.5 * length), width, length,
                                facecolor='0.85', edgecolor='0.4'))
    top.scatter(the_map.y_left[valid], the_map.x[valid], s=10, c='tab:blue', alpha=0.6,
                label='ICR$_l$ (map)')
    top.scatter(the_map.y_right[valid], the_map.x[valid], s=10, c='tab:red', alpha=0.6,
                label='ICR$_r$ (map)')
    top.plot([icr.y_left, icr.y_right], [icr.x, icr.x], 'k-', lw=1)
    top.plot([icr.y_left, icr.y_right], [icr.x, icr.x], 'kD', ms=8,
             label=f'averaged: chi {fixed(icr.chi)}, e {fixed(icr.eccentricity)}')
    top.plot([veh.com_y], [veh.com_x], 'k+', ms=14, mew=2, label='centre of mass')
    top.plot([half, -half], [0.0, 0.0], 'o', mfc='none', mec='0.3', ms=8,
             label='ideal contact points')
    top.set_aspect('equal')
    top.invert_xaxis()
    top.set_xlabel('y (m), left <- -> right')
    top.set_ylabel('x (m), forward')
    top.set_title(f'{spec.name} on {spec.terrain}: tread ICRs, top view')
    top.grid(True, alpha=0.3)
    top.legend(loc='lower center', fontsize=8, framealpha=0.9)

    v_left, v_right = the_map.v_left[valid], the_map.v_right[valid]
    phi = np.degrees(np.arctan2(v_right, v_left))
    speed = np.hypot(v_left, v_right)
    handles = []
    for arr, marker, label in ((the_map.y_left, 'o', 'icr.y_left'),
                               (the_map.y_right, 's', 'icr.y_right'), (the_map.x, '^', 'icr.x')):
        points = side.scatter(phi, arr[valid], c=speed, cmap='viridis', marker=marker, s=14)
        handles.append(side.scatter([], [], c='0.5', marker=marker, s=14, label=label))
    for value in (icr.y_left, icr.y_right, icr.x):
        side.axhline(value, color='k', lw=0.8, ls='--')
    for angle, text in ((45, 'straight'), (-135, 'reverse'), (135, 'spin left'),
                        (-45, 'spin right')):
        side.axvline(angle, color='0.6', lw=0.8, ls=':')
        side.annotate(text, (angle, 1.0), xycoords=('data', 'axes fraction'), ha='center',
                      va='bottom', fontsize=8, color='0.4')
    fig.colorbar(points, ax=side, label='|(V_l, V_r)| (m/s)')
    side.set_xlabel('direction of the track-speed pair, atan2(V_r, V_l) (deg)')
    side.set_ylabel('ICR coordinate (m); dashed: averaged model')
    side.set_xlim(-180, 180)
    side.set_xticks(range(-180, 181, 45))
    side.grid(True, alpha=0.3)
    side.legend(handles=handles, loc='center left', fontsize=8)
    fig.tight_layout()
    save(fig, path, dpi=110)


# plan_trajectory -------------------------------------------------------------------------


def plot_plan(path, plan, driven, ref, title: str) -> None:
    """
    Draw a planned path against ``driven``, shape (N, 3): the dynamic simulator's poses.

    ``ref`` is the canonical trajectory followed, or None.
    """
    fig = _figure(figsize=(6.4, 5.6))
    ax = fig.subplots()
    if ref is not None:
        ax.plot(ref.path[:, 0], ref.path[:, 1], color='tab:green', lw=4, alpha=0.5,
                label='desired (ideal drive)')
    ax.plot(plan.poses[:, 0], plan.poses[:, 1], 'r--', label=f'planned ({plan.model})')
    ax.plot(driven[:, 0], driven[:, 1], 'k-', lw=1, label='simulated with dynamics')
    gx, gy, gth = plan.goal
    ax.plot(gx, gy, 'o', color='tab:blue', label='goal')
    ax.arrow(gx, gy, 0.2 * math.cos(gth), 0.2 * math.sin(gth), width=0.01, color='tab:blue')
    ax.set_aspect('equal', adjustable='datalim')
    ax.set_xlabel('x (m)')
    ax.set_ylabel('y (m)')
    ax.set_title(title, fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save(fig, path, dpi=110)


# tracked_kinematics_demo -----------------------------------------------------------------


def plot_heldout_paths(path, results, title: str) -> None:
    """Draw each held-out path of the demo: truth, ideal, identified and gyro-aided odometry."""
    cols = 2 if len(results) in (2, 4) else min(3, len(results))
    rows = -(-len(results) // cols)
    fig = _figure(figsize=(5.0 * cols, 4.8 * rows), layout='constrained')
    fig.suptitle(title)
    for k, r in enumerate(results):
        ax = fig.add_subplot(rows, cols, k + 1)
        for label, poses, style in (
                ('ground truth', r.truth, {'color': 'black', 'lw': 2.0}),
                ('ideal diff drive', r.ideal, {'color': 'tab:red'}),
                ('identified ICRs', r.identified, {'color': 'tab:blue', 'ls': '--'}),
                ('gyro-aided', r.gyro_aided, {'color': 'tab:green', 'ls': ':', 'lw': 1.8})):
            ax.plot(poses[:, 0], poses[:, 1], label=label, **style)
        ax.plot([0.0], [0.0], 'ko', ms=4)
        pos_i, _, _ = r.errors('ideal')
        pos_c, _, _ = r.errors('identified')
        pos_g, _, _ = r.errors('gyro_aided')
        ax.set_title(f'{r.name}: {r.distance:.1f} m\nfinal error ideal {pos_i:.2f} m, '
                     f'identified {pos_c:.3f} m, gyro-aided {pos_g:.3f} m', fontsize=9)
        ax.set_aspect('equal', adjustable='datalim')
        ax.set_xlabel('x (m)')
        ax.set_ylabel('y (m)')
        ax.grid(True, alpha=0.3)
        if k == 0:
            ax.legend(fontsize=8, loc='best')
    save(fig, path, dpi=90)
