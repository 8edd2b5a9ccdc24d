"""
``icr_map``: the tread ICR map of a vehicle and its averaged constant-ICR model.

Solves the stationary track-soil model (:mod:`tracked_kinematics.core.sim.dynamics`) for every
pair of ``n`` equidistant track speeds in ``(-max_track_speed, max_track_speed)``, as Martinez
et al. (2005) do in sec. 5.2 (Figs. 6-7), prints the spread of the tread ICRs and their
average (the constant-ICR model, with chi and e, in ROS and in the paper's symbols), and
optionally plots the map, writes it as CSV, and writes the averaged model as a terrain YAML.

Exit status: 0 success; 2 bad input (vehicle, option, an output path that may not be
written, a file that cannot be written); 130 / 143 interrupted. The outputs are written
together at the end or not at all (docs/output-files.md).

Documentation: docs/tools/icr_map.md; the model: docs/model.md.
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
import time

import numpy as np
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.sim.dynamics import StationarySolver
from tracked_kinematics.core.sim.icr_maps import averaged_icr, icr_map, IcrMap
from tracked_kinematics.offline.cli.common import (
    add_force_argument, add_plot_output, ArgumentParser, bounded, run_main)
from tracked_kinematics.offline.outputs import Outputs
from tracked_kinematics.offline.vehicle_file import (
    add_vehicle_arguments, fixed, load_vehicle, overrides_from_args, vehicle_path, VehicleFile)
from tracked_kinematics.params import params_text, values_from_icr

PROG = 'icr_map'
MAX_N = 101
"""Largest --n: 101 x 101 = 10,201 stationary solutions (6.4 s, 0.6 GB)."""


def build_parser() -> argparse.ArgumentParser:
    """Argument parser of ``icr_map``."""
    parser = ArgumentParser(
        prog=PROG, formatter_class=argparse.ArgumentDefaultsHelpFormatter,
        description='Tread ICR map of a vehicle from its stationary track-soil dynamics '
                    '(Martinez et al. 2005, sec. 4.1, 5.2) and the averaged constant-ICR model.',
        epilog='examples:\n'
               '  icr_map auriga_alpha --plot auriga_map.png\n'
               '  icr_map packbot --n 41 --csv map.csv --output packbot_concrete.yaml\n'
               '  icr_map my_robot.yaml --mu-y 0.9 --set centre_of_mass.y=0.03')
    add_vehicle_arguments(parser, positional=True)
    parser.add_argument('--n', type=bounded(2, MAX_N, integer=True), default=21,
                        help=f'track speeds per track in the map (n x n pairs), 2-{MAX_N}')
    parser.add_argument('--max-speed', type=bounded(0.01, 20.0, 'm/s'), default=None,
                        help="speed range (-S, S), m/s, 0.01-20 (default: the vehicle's "
                             'max_track_speed)')
    parser.add_argument('--weighting', choices=('uniform', 'turn_rate'), default='uniform',
                        help='average of the map: plain mean (the paper) or weighted by the '
                             'squared turn rate (least squares of the inverse kinematics)')
    parser.add_argument('--plot', default=None, metavar='OUT.png', help='plot the map (PNG)')
    parser.add_argument('--csv', default=None, metavar='OUT.csv',
                        help='write every pair: speeds, twist, ICRs')
    parser.add_argument('--output', default=None, metavar='OUT.yaml',
                        help='write the averaged model as a terrain parameter file')
    add_force_argument(parser)
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


def csv_text(the_map: IcrMap) -> str:
    """Every pair of the map as a CSV row, with a header."""
    stream = io.StringIO(newline='')
    writer = csv.writer(stream)
    writer.writerow(['v_left', 'v_right', 'v_x', 'v_y', 'w', 'icr_y_left', 'icr_y_right',
                     'icr_x'])
    rows = np.column_stack([the_map.v_left.ravel(), the_map.v_right.ravel(),
                            the_map.twist.reshape(-1, 3), the_map.y_left.ravel(),
                            the_map.y_right.ravel(), the_map.x.ravel()])
    writer.writerows(rows.tolist())
    return stream.getvalue()


def write_csv(path, the_map: IcrMap, force: bool = False) -> None:
    """Write :func:`csv_text` to ``path`` through :class:`Outputs`."""
    with Outputs(force=force) as out:
        out.add('--csv', path)
        out.write_text('--csv', csv_text(the_map))


def _outputs(args) -> Outputs:
    """Check every output path before any work (docs/output-files.md)."""
    outputs = Outputs(force=args.force)
    outputs.add('--csv', args.csv)
    outputs.add('--output', args.output)
    add_plot_output(outputs, args.plot)
    outputs.refuse_inputs('VEHICLE', [vehicle_path(args.vehicle)])
    return outputs


def _run(args, out) -> int:
    with _outputs(args) as outputs:
        spec = load_vehicle(args.vehicle, overrides_from_args(args))
        start = time.perf_counter()
        veh = spec.robot.vehicle
        the_map = icr_map(veh, args.n, StationarySolver(veh), args.max_speed)
        seconds = time.perf_counter() - start
        icr = averaged_icr(the_map, args.weighting)
        print(summary(spec, the_map, icr, seconds), file=out)
        if '--csv' in outputs:
            outputs.write_text('--csv', csv_text(the_map))
        if '--output' in outputs:
            values = values_from_icr(icr, spec.robot.encoders.sprocket_radius)
            values.update({'chi': icr.chi, 'eccentricity': icr.eccentricity,
                           'vehicle': spec.name, 'terrain': spec.terrain,
                           'source': f'icr_map: {args.weighting} average of the {args.n} x '
                                     f'{args.n} stationary ICR map (Martinez sec. 5.2)'})
            outputs.write_text('--output', params_text(values, comment=(
                f'Averaged tread ICRs of {spec.name} on {spec.terrain} from the stationary '
                'dynamic model; valid as --params-file. Encoder scales are not modelled (1).')))
        if '--plot' in outputs:
            from tracked_kinematics.offline.plots import plot_icr_map
            with outputs.path('--plot') as tmp:
                plot_icr_map(tmp, spec, the_map, icr)
    for flag, what in (('--csv', 'map'), ('--output', 'averaged model'), ('--plot', 'plot')):
        if flag in outputs:
            print(f'{what} written to {outputs.target(flag)}', file=out)
    return 0


def main(argv=None) -> int:
    """Run ``icr_map``; return the exit status (see the module docstring)."""
    return run_main(PROG, _run, build_parser().parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
