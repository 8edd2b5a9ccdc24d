"""
``convert_diff_drive_params``: a diff_drive_controller configuration -> a terrain file.

Reads a ros2_control controllers file, finds its diff_drive_controller (DDC) section and
writes the parameter file that odometry_node and cmd_vel_translator load with
``--ros-args --params-file``: the vehicle (track width, sprocket radius, the ICRs from
``wheel_separation_multiplier``, the scales from the radius multipliers) for every node, and
the joints, frames, TF, timeout and limits for the node that declares them. The mapping is
:mod:`tracked_kinematics.offline.ddc`; docs/tools/convert_diff_drive_params.md lists it.

Prints what it mapped (``DDC key = value -> our key = value``) and what it could not map and
why; warnings (the converted robot differs from the DDC one) go to stderr. Exit status 0
written; 2 for bad input (missing or unreadable file, not YAML, no DDC section or several
without ``--controller``, no ``wheel_separation`` / ``wheel_radius``, invalid values) or an
output that may not be written; nothing is written then; 130, 143 interrupted (Ctrl-C,
SIGTERM), nothing written (docs/output-files.md).
"""

from __future__ import annotations

import argparse
import os
import sys

from tracked_kinematics.offline.cli.common import run_main
from tracked_kinematics.offline.ddc import convert_file, report_lines
from tracked_kinematics.offline.outputs import OutputError, Outputs

PROG = 'convert_diff_drive_params'

_EPILOG = """\
examples:
  convert_diff_drive_params controllers.yaml --output terrain.yaml
  convert_diff_drive_params controllers.yaml --controller diff_drive_base_controller \\
      --output terrain.yaml --force
  ros2 run tracked_kinematics odometry_node --ros-args --params-file terrain.yaml
"""


def build_parser() -> argparse.ArgumentParser:
    """Return the command line of ``convert_diff_drive_params``."""
    parser = argparse.ArgumentParser(
        prog=PROG, formatter_class=argparse.RawDescriptionHelpFormatter, epilog=_EPILOG,
        description='Convert the diff_drive_controller section of a ros2_control controllers '
                    'file into a parameter file for odometry_node and cmd_vel_translator, and '
                    'say what was mapped and what not.')
    parser.add_argument('controllers', metavar='CONTROLLERS.yaml',
                        help='ros2_control controllers file (controller_manager and '
                             'controller sections)')
    parser.add_argument('--controller', metavar='NAME',
                        help='name of the DiffDriveController section, when the file has '
                             'several (or to pick one by name)')
    parser.add_argument('--output', '-o', metavar='TERRAIN.yaml', required=True,
                        help='parameter file to write')
    parser.add_argument('--force', action='store_true',
                        help='replace --output if it exists')
    return parser


def _same_file(a: str, b) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _run(args, out) -> int:
    with Outputs(force=args.force) as outputs:
        target = outputs.add('--output', args.output)
        if _same_file(args.controllers, target):
            raise OutputError(f'--output {target} is the input file; choose another path')
        conversion = convert_file(args.controllers, args.controller)
        outputs.write_text('--output', conversion.yaml_text(source=args.controllers))
    print('\n'.join(report_lines(conversion)), file=out)
    print(f'\nwrote {target}: ' + ', '.join(
        f'{section} {len(values)} parameters'
        for section, values in conversion.sections().items()), file=out)
    out.flush()
    for warning in conversion.warnings:
        print(f'{PROG}: warning: {warning}', file=sys.stderr)
    return 0


def main(argv=None) -> int:
    """Run ``convert_diff_drive_params``; return the exit status."""
    return run_main(PROG, _run, build_parser().parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
