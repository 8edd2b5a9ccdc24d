"""
``icr_map``: the tread ICR map of a vehicle and its averaged constant-ICR model.

Solves the stationary track-soil model (:mod:`tracked_kinematics.core.sim.dynamics`) for every
pair of ``n`` equidistant track speeds in ``(-max_track_speed, max_track_speed)``, as Martinez
et al. (2005) do in sec. 5.2 (Figs. 6-7), prints the spread of the tread ICRs and their
average (the constant-ICR model, with chi and e, in ROS and in the paper's symbols), and
optionally plots the map, writes it as CSV, and writes the averaged model as a terrain YAML.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time

import numpy as np
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.sim.dynamics import averaged_icr, icr_map, IcrMap, StationarySolver
from tracked_kinematics.offline.vehicle_file import (
    add_vehicle_arguments, fixed, load_vehicle, overrides_from_args, VehicleFile)
from tracked_kinematics.params import values_from_icr, write_params_file

PROG = 'icr_map'


def build_parser() -> argparse.ArgumentParser:
    """Argument parser of ``icr_map``."""
    parser = argparse.ArgumentParser(
        prog=PROG, formatter_class=argparse.ArgumentDefaultsHelpFormatter,
        description='Tread ICR map of a vehicle from its stationary track-soil dynamics '
                    '(Martinez et al. 2005, sec. 4.1, 5.2) and the averaged constant-ICR model.',
        epilog='examples:\n'
               '  icr_map auriga_alpha --plot auriga_map.png\n'
               '  icr_map packbot --n 41 --csv map.csv --output packbot_concrete.yaml\n'
               '  icr_map my_robot.yaml --mu-y 0.9 --set centre_of_mass.y=0.03')
    add_vehicle_arguments(parser, positional=True)
    parser.add_argument('--n', type=int, default=21,
                        help='track speeds per track in the map (n x n pairs)')
    parser.add_argument('--max-speed', type=float, default=None,
                        help="speed range (-S, S), m/s (default: the vehicle's max_track_speed)")
    parser.add_argument('--weighting', choices=('uniform', 'turn_rate'), default='uniform',
                        help='average of the map: plain mean (the paper) or weighted by the '
                             'squared turn rate (least squares of the inverse kinematics)')
    parser.add_argument('--plot', default=None, metavar='OUT.png', help='plot the map (PNG)')
    parser.add_argument('--csv', default=None, metavar='OUT.csv',
                        help='write every pair: speeds, twist, ICRs')
    parser.add_argument('--output', default=None, metavar='OUT.yaml',
                        help='write the averaged model as a terrain parameter file')
    return parser


def summary(spec: VehicleFile, the_map: IcrMap, icr: IcrParams, seconds: float) -> str:
    """Format the table printed on stdout."""
    veh = spec.robot.vehicle
    valid = the_map.valid
    n = len(the_map.speeds)
    lines = [
        f'vehicle   {spec.name} on {spec.terrain} ({spec.path})',
        f'          track width {veh.track_width} m, contact {veh.contact_length} x '
        f'{veh.contact_width} m, {veh.mass} kg, centre of mass ({veh.com_x}, {veh.com_y}, '
        f'{veh.com_height}) m, mu_x {veh.mu_x}, mu_y {veh.mu_y}'
        + ('' if veh.inertial else ' (no inertia)'),
        f'map       {n} x {n} pairs of track speeds in +-{the_map.speeds[-1]:g} m/s: '
        f'{int(valid.sum())} turning, {the_map.failed} failed, {seconds:.2f} s',
        '',
        f'{"ICR (ROS, m)":<16}{"min":>9}{"mean":>9}{"max":>9}{"model":>9}',
    ]
    for label, arr, value in (('icr.y_left', the_map.y_left, icr.y_left),
                              ('icr.y_right', the_map.y_right, icr.y_right),
                              ('icr.x', the_map.x, icr.x)):
        vals = arr[valid]
        lines.append(f'{label:<16}' + ''.join(f'{fixed(v, 4):>9}' for v in (
            vals.min(), vals.mean(), vals.max(), value)))
    paper = icr.to_paper()
    lines += [
        '',
        f'averaged model: chi = {fixed(icr.chi)}, e = {fixed(icr.eccentricity)}',
        f'paper symbols:  x_ICRl = {fixed(paper["x_icr_left"], 4)} m, x_ICRr = '
        f'{fixed(paper["x_icr_right"], 4)} m, y_ICRv = {fixed(paper["y_icr"], 4)} m',
    ]
    return '\n'.join(lines)


def write_csv(path, the_map: IcrMap) -> None:
    """Every pair of the map as a CSV row."""
    with open(path, 'w', newline='', encoding='utf-8') as stream:
        writer = csv.writer(stream)
        writer.writerow(['v_left', 'v_right', 'v_x', 'v_y', 'w', 'icr_y_left', 'icr_y_right',
                         'icr_x'])
        rows = np.column_stack([the_map.v_left.ravel(), the_map.v_right.ravel(),
                                the_map.twist.reshape(-1, 3), the_map.y_left.ravel(),
                                the_map.y_right.ravel(), the_map.x.ravel()])
        writer.writerows(rows.tolist())


def plot(path, spec: VehicleFile, the_map: IcrMap, icr: IcrParams) -> None:
    """
    Plot the map: tread ICRs seen from above, and their dependence on the speed pair.

    Left: every turning pair's ICR_l and ICR_r in base_link, drawn as seen from above with
    the vehicle's front up and its left on the left (like the paper's Figs. 6-7), over the
    contact patches, the centre of mass and the averaged model. Right: the ICR coordinates
    against the direction of the track-speed pair, coloured by its magnitude.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    veh = spec.robot.vehicle
    valid = the_map.valid
    fig, (top, side) = plt.subplots(1, 2, figsize=(13, 6), gridspec_kw={'width_ratios': [1, 1.3]})
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
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    """Run ``icr_map``; return the exit status."""
    args = build_parser().parse_args(argv)
    try:
        if args.n < 2:
            raise ValueError(f'--n must be >= 2, got {args.n}')
        spec = load_vehicle(args.vehicle, overrides_from_args(args))
        start = time.perf_counter()
        veh = spec.robot.vehicle
        the_map = icr_map(veh, args.n, StationarySolver(veh), args.max_speed)
        seconds = time.perf_counter() - start
        icr = averaged_icr(the_map, args.weighting)
    except (OSError, ValueError) as err:
        print(f'{PROG}: {err}', file=sys.stderr)
        return 2
    print(summary(spec, the_map, icr, seconds))
    try:
        if args.csv:
            write_csv(args.csv, the_map)
            print(f'map written to {args.csv}')
        if args.output:
            values = values_from_icr(icr, spec.robot.encoders.sprocket_radius)
            values.update({'chi': icr.chi, 'eccentricity': icr.eccentricity,
                           'vehicle': spec.name, 'terrain': spec.terrain,
                           'source': f'icr_map: {args.weighting} average of the {args.n} x '
                                     f'{args.n} stationary ICR map (Martinez sec. 5.2)'})
            write_params_file(args.output, values, comment=(
                f'Averaged tread ICRs of {spec.name} on {spec.terrain} from the stationary '
                'dynamic model; valid as --params-file. Encoder scales are not modelled (1).'))
            print(f'averaged model written to {args.output}')
        if args.plot:
            plot(args.plot, spec, the_map, icr)
            print(f'plot written to {args.plot}')
    except OSError as err:
        print(f'{PROG}: {err}', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
