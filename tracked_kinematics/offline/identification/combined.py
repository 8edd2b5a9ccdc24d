"""
identify_icr with a pose and a gyro: one fit of the segments on the headings fused by noise.

:func:`icr_from_pose_and_gyro` checks that the gyro turns as the pose does
(:func:`~tracked_kinematics.core.identify.reference.heading_fusion.check_gyro_against_pose`;
a gyro that does not is left out, named), fuses the two headings, each weighted by its
measured noise
(:func:`~tracked_kinematics.core.identify.reference.heading_fusion.fuse_heading`), and fits
the segments (:func:`.poses.icr_from_poses`: the same hold-out table, plot, standard errors and
DDC snippet as the pose alone) on the pose's positions and the fused heading. As a safety
net it compares, on an internal hold-out (leave one bag out, or the two halves of one bag),
the combined fit with the pose-alone fit and keeps the better, saying which and why. The
gyro's constants (``imu_delay``, ``gyro_scale``, ``gyro_bias``, ``gyro_bias_sigma``) are
written either way. docs/tools/identify_icr.md, "Which references to give".
"""

from __future__ import annotations

from dataclasses import replace
import math

import numpy as np

from tracked_kinematics.core import evaluate as ev
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.errors import IdentificationError
from tracked_kinematics.core.identify.reference.heading_fusion import fuse_heading

from .noise_constants import add_extras, gyro_aided_extras, gyro_extras
from .poses import icr_from_poses

MARGIN = 0.02
"""The combined fit is kept when its internal hold-out error is this much below the pose's.

A tie goes to the pose alone: on the Warthog runs the two differ by noise (the lidar ICP's
heading is as good as the gyro's over a second), and a tie broken either way must not cost
2 % on held-out data."""
MIN_SPLIT = 60.0
"""s: one recording at least this long is split in two halves for the internal hold-out."""


def time_split(rec, fraction: float = 0.5):
    """Return a recording cut at ``fraction`` of its encoder time span: (first, second)."""
    cut = rec.enc_t[0] + fraction * (rec.enc_t[-1] - rec.enc_t[0])

    def part(keep):
        changes = {}
        for prefix, names in (('enc', ('left', 'right')), ('gt', ('gt_x', 'gt_y', 'gt_yaw')),
                              ('gyro', ('gyro_rate', 'gyro_yaw'))):
            t = getattr(rec, f'{prefix}_t')
            if t is None:
                continue
            mask = keep(t)
            changes[f'{prefix}_t'] = t[mask]
            for n in names:
                v = getattr(rec, n)
                if v is not None:
                    changes[n] = v[mask]
        return replace(rec, **changes)
    return part(lambda t: t < cut), part(lambda t: t >= cut)


def _folds(recordings):
    """Return the internal hold-out folds ``(train, test)`` as lists of index pairs."""
    n = len(recordings)
    if n >= 2:
        return [([k for k in range(n) if k != h], [h]) for h in range(n)]
    return []


WINDOWS = ((5.0, 10.0), (1.0,))
"""Window lengths the internal hold-out scores, s: evaluate_model's; 1 s where the data are
in pieces too short for those (the windowed Warthog bags: 2-s pieces)."""


def _score(icr, tests, track_width, min_speed, lengths) -> float:
    """Mean position error after ``lengths`` s on held-out recordings (their delay removed)."""
    report = ev.evaluate([ev.Data(r) for r in tests], [ev.Candidate('m', icr)],
                         ev.Settings(windows=lengths, track_width=track_width,
                                     min_speed=min_speed))
    windows = report.models['m']['odometry']['windows']
    values = [w.get('mean_position_error_m') for w in windows.values()]
    values = [v for v in values if v is not None and math.isfinite(v)]
    return float(np.mean(values)) if values else math.nan


def compare_on_holdout(raw, fused, corrected, options, track_width, base):
    """
    Fit the pose alone and the fused headings on training parts; score both on the rest.

    Returns ``(pose_score, fused_score, how)``: mean held-out position error (m) after 5 and
    10 s of each (after 1 s on data in shorter pieces, :data:`WINDOWS`), NaN when there is
    nothing to hold out.
    """
    pairs = list(zip(raw, fused, corrected))
    if len(pairs) == 1 and raw[0].enc_t[-1] - raw[0].enc_t[0] >= MIN_SPLIT:
        halves = [tuple(time_split(r) for r in p) for p in pairs]
        pairs = [tuple(h[0] for h in halves[0]), tuple(h[1] for h in halves[0])]
        how = 'the two halves of the bag, each held out once'
    else:
        how = 'leave one bag out'
    folds = _folds(pairs)
    if not folds:
        return math.nan, math.nan, 'nothing to hold out (one short bag)'
    settings = replace(options.identify, holdout=0.0, accept_uncertain=True)
    icrs = {0: [], 1: []}
    for train, _ in folds:
        for which in (0, 1):
            try:
                icrs[which].append(ident.identify([pairs[k][which] for k in train],
                                                  options.model, track_width, base=base,
                                                  options=settings).icr)
            except (IdentificationError, ValueError):
                icrs[which].append(None)
    for lengths in WINDOWS:
        scores = {which: [_score(icr, [pairs[k][2] for k in test], track_width,
                                 settings.min_speed, lengths) if icr is not None else math.inf
                          for icr, (_, test) in zip(icrs[which], folds)] for which in (0, 1)}
        pose, fused = float(np.mean(scores[0])), float(np.mean(scores[1]))
        if not (math.isnan(pose) or math.isnan(fused)):
            break
    after = ' and '.join(f'{w:g} s' for w in lengths)
    return pose, fused, f'{how}, mean position error after {after}'


def icr_from_pose_and_gyro(recordings, options, topic: str, track_width: float,
                           sprocket_radius: float, *, base=None, base_values=None,
                           date=None):
    """
    Fit from a pose and a gyro (read together, one bag each); return the :class:`FitResult`.

    The gyro is checked against the pose and its constants found first
    (:func:`.noise_constants.gyro_extras`); a gyro refused there is left out of the fit too.
    """
    recordings = list(recordings)
    extras, gyro = gyro_extras(recordings, topic, imu_delay=options.imu_delay)
    choice = []
    chosen = recordings
    if gyro is not None:
        corrected, imu_delay, scale = gyro
        fused_c, fusion = fuse_heading(corrected, imu_delay, scale)
        # Back on the raw stamps: identify measures and removes the pose's delay itself.
        fused = [replace(r, gt_yaw=f.gt_yaw) for r, f in zip(recordings, fused_c)]
        pose_score, fused_score, how = compare_on_holdout(
            recordings, fused, corrected, options, track_width, base)
        noise = (f'pose heading noise {math.degrees(fusion.sigma_pose):.2f} deg, gyro random '
                 f'walk {math.degrees(fusion.q):.3f} deg/sqrt(s): headings fused over '
                 f'{fusion.window:.1f} s')
        if math.isnan(pose_score) or fused_score < (1.0 - MARGIN) * pose_score:
            chosen = fused
            why = ('kept: pose + gyro (nothing to compare it with the pose alone on)'
                   if math.isnan(pose_score) else
                   f"kept: pose + gyro ({fused_score:.3f} m against the pose alone's "
                   f'{pose_score:.3f} m on {how})')
        else:
            why = (f"kept: the pose alone ({pose_score:.3f} m against pose + gyro's "
                   f'{fused_score:.3f} m on {how}; '
                   f'pose + gyro is kept when {MARGIN:.0%} better); '
                   "the gyro's constants are written all the same")
        choice = [f'pose + gyro {topic}: {noise}; {why}']
        extras = replace(extras, record={
            **extras.record, 'fused_heading': chosen is fused,
            'fusion_window': fusion.window, 'pose_heading_noise': fusion.sigma_pose,
            'holdout_pose_alone_m': pose_score, 'holdout_pose_and_gyro_m': fused_score},
            report={**extras.report, 'choice': {
                'kept': 'pose+gyro' if chosen is fused else 'pose', 'how': how,
                'pose_alone_m': pose_score, 'pose_and_gyro_m': fused_score,
                'fusion_window_s': fusion.window, 'pose_heading_noise_rad': fusion.sigma_pose,
                'gyro_random_walk_rad_sqrt_s': fusion.q}})
    found = icr_from_poses(chosen, options, track_width, sprocket_radius, base=base,
                           base_values=base_values, date=date)
    values, report, lines = dict(found.values), dict(found.report), list(found.lines)
    add_extras(values, report, lines, replace(extras, lines=tuple(choice) + extras.lines))
    if gyro is not None:
        values['identification.reference'] = 'pose+imu' if chosen is not recordings else 'pose'
        if found.identification is not None and 'covariance.k_left' in values:
            # The gyro-aided odometry's own noise model, on its windows against the pose.
            add_extras(values, report, lines, gyro_aided_extras(
                values, gyro[0], track_width, found.identification.min_speed))
    return replace(found, values=values, report=report, lines=tuple(lines))
