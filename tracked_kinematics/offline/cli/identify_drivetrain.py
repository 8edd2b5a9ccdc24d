"""
identify_drivetrain: fit the drive-train model of the tracks from recorded rosbags.

Reads the commanded track speeds (the setpoints cmd_vel_translator publishes, or a cmd_vel
turned into track speeds through the ideal inverse, as a diff_drive_controller base does) and
the measured ones (the track encoders) from one or more bags, fits the command delay, the
acceleration limit and the speed loop of Fink & Stump sec. III-B, and writes them as the
``drivetrain.*`` parameters of a terrain file, so that a motion prediction can start from
the commands instead of the measured speeds.

Exit status, as identify_icr: 0 success; 2 bad input (missing bag, topic or joint;
unreadable bag; invalid option; an output path that may not be written); 3 too little data,
or commands that hardly change; 4 the fit failed (best delay at the search bound, no
convergence); 130 / 143 interrupted. The outputs are written together at the end or not at
all (docs/output-files.md).

Documentation: docs/tools/identify_drivetrain.md; the ``drivetrain.*`` parameters:
docs/parameters.md.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from datetime import datetime, timezone
import math
from pathlib import Path
import sys

from tracked_kinematics.core.drivetrain import LOOP_KINDS
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.core.identify import fit_drivetrain
from tracked_kinematics.offline.bags import read_recording
from tracked_kinematics.offline.cli.common import (
    add_base_file_argument, add_command_arguments, add_encoder_arguments, add_output_argument,
    add_plot_output, add_report_arguments, add_sprocket_radius_argument, bag_tool_parser,
    bounded, command_source, encoder_source, positive, read_base_file, refuse_another_vehicle,
    report_json, require_vehicle, run_main, write_together)
from tracked_kinematics.offline.errors import BagError, UsageError
from tracked_kinematics.offline.outputs import Outputs
from tracked_kinematics.offline.terrain_file import terrain_text, terrain_values
from tracked_kinematics.params import (
    drivetrain_from_values, positive as check_positive, values_from_drivetrain)

PROG = 'identify_drivetrain'
MAX_GRID_SAMPLES = 2_000_000
"""Largest grid (seconds of data / --dt) the fit allocates: 5.5 h of data at 10 ms."""
_UNITS = {'delay': 's', 'max_accel': 'm/s^2', 'time_constant': 's', 'kp': '', 'ki': '',
          'kd': ''}

EPILOG = """examples:
  identify_drivetrain run1/ run2/ --output drive.yaml --sprocket-radius 0.1
  identify_drivetrain calib.bag --params hard_floor.yaml --output hard_floor.yaml --force \\
      --report drive.json --plot drive.png
  identify_drivetrain packbot/ --loop pid_dc_motor --params packbot_base.yaml -o packbot.yaml
"""


def build_parser() -> argparse.ArgumentParser:
    """Return the command line of identify_drivetrain."""
    parser = bag_tool_parser(PROG, __doc__, EPILOG)
    add_output_argument(parser)
    cmd = parser.add_argument_group('commands')
    add_command_arguments(cmd, kinds=('auto', 'setpoints', 'cmd_vel'))
    cmd.add_argument('--track-width', type=positive, default=None, metavar='L',
                     help='m, of the ideal inverse that turns cmd_vel into track speeds; '
                     'default from --params')
    enc = parser.add_argument_group('encoders (measured speeds)')
    add_encoder_arguments(enc)
    add_sprocket_radius_argument(enc)
    fit = parser.add_argument_group('fit')
    add_base_file_argument(fit, 'sprocket radius, starting point, fixed motor constants of '
                           '--loop pid_dc_motor')
    fit.add_argument('--loop', choices=LOOP_KINDS, default='first_order',
                     help='speed loop to fit: first-order lag, PID gains around the fixed DC '
                     'motor of eq. (8), or none')
    fit.add_argument('--dt', type=bounded(0.001, 0.1, 's'), default=None, metavar='SECONDS',
                     help='grid period and delay resolution (default: the encoder period, '
                     'within 0.002-0.02 s)')
    fit.add_argument('--max-delay', type=bounded(0.0, 2.0, 's'), default=0.5, metavar='SECONDS',
                     help='largest command delay searched')
    fit.add_argument('--max-gap', type=bounded(0.0, 60.0, 's'), default=0.5, metavar='SECONDS',
                     help='longer gaps in either stream cut the data into segments')
    add_report_arguments(parser.add_argument_group('output'),
                         report='JSON report: values, standard errors, RMS, delay profile',
                         plot='commanded, measured and simulated speeds, and the delay profile')
    return parser


def _base(args):
    """Read the base terrain values, the sprocket radius and the base drive train (or None)."""
    base_values = read_base_file(PROG, args.params)
    refuse_another_vehicle(args.params, base_values, args.track_width, args.sprocket_radius)
    radius = args.sprocket_radius
    if radius is None:
        radius = base_values.get('sprocket_radius')
    require_vehicle({'--sprocket-radius': radius})
    if check_positive(radius):
        raise UsageError(f'{args.params}: sprocket_radius must be a finite number > 0, got '
                         f'{radius!r}')
    if args.track_width is None and 'track_width' in base_values:
        width = base_values['track_width']
        if check_positive(width):
            raise UsageError(f'{args.params}: track_width must be a finite number > 0, got '
                             f'{width!r}')
        args.track_width = float(width)
    base = None
    if any(k.startswith('drivetrain.') for k in base_values):
        try:
            base = drivetrain_from_values(base_values)
        except InvalidParameters as err:
            raise UsageError(f'{args.params}: {err}') from None
    return base_values, float(radius), base


def _yaml_values(base_values, result, radius, extras):
    """Merge base values without old drive-train keys, the fitted model and the fit's record."""
    fitted = {'sprocket_radius': radius, **values_from_drivetrain(result.drivetrain)}
    return terrain_values(base_values, fitted, record='drivetrain_fit', extras=extras,
                          check=drivetrain_from_values, drop=('drivetrain.',))


def _print_table(result, recordings, out):
    seconds = sum(float(s.t[-1] - s.t[0]) for s in result.segments)
    print(f'{PROG}: {len(recordings)} bag(s), {seconds:.1f} s of commanded and measured speeds '
          f'in {len(result.segments)} segment(s); grid {1000 * result.dt:.0f} ms; loop '
          f'{result.loop}', file=out)
    print(f'{"parameter":<16}{"value":>12}{"std. error":>14}  unit', file=out)
    for name, value in result.parameters.items():
        error = result.standard_errors.get(name, math.nan)
        shown = 'none' if math.isinf(value) else f'{value:.4f}'
        err = '' if not math.isfinite(error) else f'{error:.2g}'
        print(f'{name:<16}{shown:>12}{err:>14}  {_UNITS.get(name, "")}'.rstrip(), file=out)
    if math.isinf(result.drivetrain.max_accel):
        print(f'acceleration limit: never binds (commands change at up to '
              f'{result.max_command_accel:.2f} m/s^2); written as 0 = none', file=out)
    else:
        print(f'acceleration limit binds on {100 * result.accel_limit_binding:.1f} % of samples',
              file=out)
    if result.fixed:
        fixed = ', '.join(f'{k} {v:g}' for k, v in result.fixed.items())
        print(f'motor constants held fixed: {fixed}', file=out)
    print(f'delay: of the measured speeds (encoder stamps) behind the setpoints (bag receive '
          f'times), any clock offset between the two included; its standard error from '
          f'{result.delay_uncertainty}', file=out)
    if result.delay_at_zero:
        print('note: the best delay is 0, the lower end of the search: the lag of the loop may '
              'absorb the delay (a loop that does not fit: see the rms), or the measured '
              'speeds lead the setpoint stamps (setpoints stamped late, on receipt)', file=out)
    print(f'rms error {1000 * result.rms:.1f} mm/s over {result.samples} samples per track '
          f'(commands taken as speeds: {1000 * result.rms_commands:.1f} mm/s); fit '
          f'{result.fit_percent:.1f} %; {result.delays_fitted} delays tried, {result.nfev} '
          f'simulations, {result.seconds:.2f} s', file=out)


def _outputs(args) -> Outputs:
    """Check every output path before any work (docs/output-files.md)."""
    outputs = Outputs(force=args.force)
    outputs.add('--output', args.output)
    outputs.add('--report', args.report)
    add_plot_output(outputs, args.plot)
    outputs.refuse_inputs('BAG', args.bags)
    outputs.refuse_inputs('--params', [args.params], allow=('--output',))
    return outputs


def _check_grid(args, recordings) -> None:
    """Refuse a --dt whose grid over the data would exceed MAX_GRID_SAMPLES, before the fit."""
    if args.dt is None:
        return
    seconds = 0.0
    for r in recordings:
        times = [t for t in (r.command_t, r.speed_t) if t is not None and len(t)]
        if times:
            seconds += max(float(t[-1]) for t in times) - min(float(t[0]) for t in times)
    samples = seconds / args.dt
    if samples > MAX_GRID_SAMPLES:
        raise UsageError(f'--dt {args.dt:g} s over {seconds:.0f} s of data is a grid of '
                         f'{samples:,.0f} samples (at most {MAX_GRID_SAMPLES:,}); give a '
                         'larger --dt or fewer bags')


def _run(args, out) -> int:
    return write_together(_outputs(args), lambda outputs: _identify(args, out, outputs), out)


def _identify(args, out, outputs) -> None:
    base_values, radius, base = _base(args)
    encoders = encoder_source(args, radius)
    progress = sys.stderr.isatty()
    commands = replace(command_source(args, args.track_width), required=True)
    recordings = [read_recording(b, encoders, commands=commands, progress=progress)
                  for b in args.bags]
    for r in recordings:
        if r.speed_t is None and len(r.enc_t) < 2:
            raise BagError(f'{r.name}: fewer than two encoder samples')
    _check_grid(args, recordings)
    result = fit_drivetrain(recordings, loop=args.loop, dt=args.dt, max_delay=args.max_delay,
                            max_gap=args.max_gap, base=base)
    date = datetime.now(timezone.utc).isoformat(timespec='seconds')
    bags = [str(Path(b).resolve()) for b in args.bags]
    extras = {'loop': result.loop, 'date': date, 'bags': bags, 'rms': result.rms,
              'rms_commands': result.rms_commands, 'fit_percent': result.fit_percent,
              'seconds_of_data': result.seconds_of_data, 'dt': result.dt,
              'accel_limit_binding': result.accel_limit_binding,
              'delay_uncertainty': result.delay_uncertainty}
    extras.update({f'standard_errors.{k}': v for k, v in result.standard_errors.items()})
    values = _yaml_values(base_values, result, radius, extras)
    _print_table(result, recordings, out)
    outputs.write_text('--output', terrain_text(
        values, tool=PROG, date=date, contents='Terrain parameters with the drive train'))
    if '--report' in outputs:
        outputs.write_text('--report', report_json({
            'tool': PROG, 'date': date, 'bags': bags, 'sprocket_radius': radius,
            'loop': result.loop, 'parameters': result.parameters,
            'standard_errors': result.standard_errors, 'fixed': result.fixed,
            'rms': result.rms, 'rms_commands': result.rms_commands,
            'fit_percent': result.fit_percent,
            'accel_limit_binding': result.accel_limit_binding,
            'max_command_accel': result.max_command_accel, 'dt': result.dt,
            'samples': result.samples, 'seconds_of_data': result.seconds_of_data,
            'segments': len(result.segments), 'delays_fitted': result.delays_fitted,
            'delay_uncertainty': result.delay_uncertainty,
            'delay_at_zero': result.delay_at_zero,
            'simulations': result.nfev, 'seconds': result.seconds,
            'delay_profile': {'delay': result.delay_profile[0],
                              'rms': result.delay_profile[1]}}))
    if '--plot' in outputs:
        from tracked_kinematics.offline.plots import plot_drivetrain
        with outputs.path('--plot') as tmp:
            plot_drivetrain(tmp, result)


def main(argv=None) -> int:
    """Run identify_drivetrain; return the exit status (see the module docstring)."""
    return run_main(PROG, _run, build_parser().parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
