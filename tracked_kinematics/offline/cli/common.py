"""
What the offline command-line tools share: parser, argument types, options, reports, errors.

The parser with one-line usage errors, argument types with ranges, the encoder options,
``--force``, JSON reports, warnings, and :func:`run_main` (errors, signals, exit status).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
import math
import signal
import sys

from tracked_kinematics.core.errors import TrackedKinematicsError
from tracked_kinematics.core.identify.procedure import MIN_SPEED
from tracked_kinematics.offline import signals
from tracked_kinematics.offline.bags import (
    CMD_VEL_TOPIC, COMMAND_KINDS, CommandSource, EncoderSource, GroundTruthSource,
    SETPOINT_TOPICS)
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.outputs import abort_unfinished, begun, Outputs
from tracked_kinematics.offline.signals import Signalled
from tracked_kinematics.offline.tooling import (  # noqa: F401 (the tools import them here)
    checked_encoders, error_line, EXIT_EXCITATION, EXIT_FIT, EXIT_INPUT, exit_status,
    imu_mount_of, read_base_file, refuse_another_vehicle, report_json, require_vehicle, warn,
    warn_unknown_terrain_keys)
from tracked_kinematics.params import (
    ENCODER_INPUT_DEFAULTS, GYRO_PARAMS, INPUT_MODES, SIDE_TOPICS)

EXIT_INTERRUPTED = 130
"""Exit status after Ctrl-C (SIGINT); after SIGTERM or SIGHUP it is 128 + the signal."""


class ArgumentParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line on stderr, exit status 2."""

    def error(self, message):
        """Print ``PROG: error: MESSAGE (see PROG --help)`` and exit with status 2."""
        self.exit(EXIT_INPUT, f'{self.prog}: error: {" ".join(message.split())} '
                              f'(see {self.prog} --help)\n')


def names(text: str) -> tuple[str, ...]:
    """Argument type: comma-separated names."""
    found = tuple(n.strip() for n in text.split(',') if n.strip())
    if not found:
        raise argparse.ArgumentTypeError('expected comma-separated names')
    return found


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a number, got {text!r}') from None


def topic_pair(text: str) -> tuple[str, str]:
    """Argument type: ``LEFT,RIGHT`` topics."""
    topics = names(text)
    if len(topics) != 2:
        raise argparse.ArgumentTypeError(f'expected LEFT,RIGHT topics, got {text!r}')
    return topics


def positive(text: str) -> float:
    """Argument type: a finite number > 0."""
    value = _number(text)
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f'must be a finite number > 0, got {text}')
    return value


def non_negative(text: str) -> float:
    """Argument type: a finite number >= 0."""
    value = _number(text)
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f'must be a finite number >= 0, got {text}')
    return value


def _g(value: float) -> str:
    return f'{value:,}' if isinstance(value, int) else f'{value:g}'


def bounded(low: float, high: float, unit: str = '', *, zero: bool = False,
            integer: bool = False):
    """
    Return an argument type: a number in ``[low, high]`` (with ``zero``, 0 too).

    The range is what a real robot needs (docs/tools/*.md list them); a value outside is
    refused before any work, so that no flag can make a tool allocate or compute without
    bound. ``integer`` asks for a whole number. The type's ``words`` say the range.
    """
    unit_text = f' {unit}' if unit else ''
    words = f'in [{_g(low)}, {_g(high)}]{unit_text}' + (' or 0' if zero else '')

    def parse(text: str):
        if integer:
            try:
                value = int(text, 10)
            except ValueError:
                raise argparse.ArgumentTypeError(
                    f'expected a whole number, got {text!r}') from None
        else:
            value = _number(text)
        if (zero and value == 0) or (math.isfinite(value) and low <= value <= high):
            return value
        finite = '' if math.isfinite(value) else 'a finite number '
        raise argparse.ArgumentTypeError(f'must be {finite}{words}, got {text}')
    parse.words = words
    parse.__name__ = 'integer' if integer else 'number'
    return parse


SEED = bounded(0, 2**32 - 1, integer=True)
"""Argument type of ``--seed``: a whole number in [0, 2^32 - 1]."""


class HelpFormatter(argparse.RawDescriptionHelpFormatter,
                    argparse.ArgumentDefaultsHelpFormatter):
    """Show defaults, except the empty ones; keep the examples' lines."""

    def __init__(self, prog):
        super().__init__(prog, width=96)

    def _get_help_string(self, action):
        if action.default in (None, False, '') or action.required:
            return action.help
        return super()._get_help_string(action)


def add_bags_argument(parser) -> None:
    """Add the positional bags of an identification tool."""
    parser.add_argument('bags', nargs='+', metavar='BAG',
                        help='rosbag2 directories (sqlite3, mcap) or ROS 1 .bag files')


def bag_tool_parser(prog: str, doc: str, epilog: str) -> ArgumentParser:
    """
    Return the parser of a tool that reads bags, with its positional ``BAG`` arguments.

    Parameters
    ----------
    prog : str
        The console script's name.
    doc : str
        The tool module's docstring: its second paragraph is the ``--help`` description.
    epilog : str
        The examples, kept line by line; defaults are shown (:class:`HelpFormatter`).

    """
    parser = ArgumentParser(prog=prog, description=doc.split('\n\n')[1], epilog=epilog,
                            formatter_class=HelpFormatter)
    add_bags_argument(parser)
    return parser


def identification_parser(prog: str, doc: str, epilog: str, ground_truth: str) -> ArgumentParser:
    """
    Return the parser of a tool that compares encoders with a reference: bags, the pose topic.

    :func:`bag_tool_parser` with an optional ``--ground-truth-topic`` (``ground_truth``: what
    its help adds, the alternative to it: ``' (or --imu-topic)'``).
    """
    parser = bag_tool_parser(prog, doc, epilog)
    add_ground_truth_topic_argument(parser, required=False, extra=ground_truth)
    return parser


def add_vehicle_groups(parser, track_width_help: str):
    """
    Add the ``encoders`` group and the ``vehicle`` group; return the vehicle group.

    The encoders: :func:`add_encoder_arguments`; the vehicle: ``--sprocket-radius``
    (:func:`add_sprocket_radius_argument`) and ``--track-width L`` (:data:`TRACK_WIDTH`),
    with its help ``track_width_help`` (each tool says where its default comes from).
    """
    add_encoder_arguments(parser.add_argument_group('encoders'))
    veh = parser.add_argument_group('vehicle')
    add_sprocket_radius_argument(veh)
    veh.add_argument('--track-width', type=TRACK_WIDTH, default=None, metavar='L',
                     help=track_width_help)
    return veh


def add_window_selection_arguments(group) -> None:
    """
    Add ``--min-speed`` and ``--all-windows``: the windows scored are those the vehicle moves in.

    Read them with :func:`min_speed`.
    """
    group.add_argument('--min-speed', type=MIN_SPEED_RANGE, default=MIN_SPEED, metavar='M/S',
                       help='score the windows in which the vehicle moves: mean track speed '
                       '((|left| + |right|) / 2 of the nominal track speeds, averaged over the '
                       'window) at least this')
    group.add_argument('--all-windows', action='store_true',
                       help='score every window, idle ones too (--min-speed is ignored)')


def min_speed(args) -> float | None:
    """Return the mean track speed from which a window is scored, m/s; None: every window."""
    return None if args.all_windows else args.min_speed


def add_base_file_argument(group, starts: str) -> None:
    """Add ``--params BASE.yaml``, the terrain file a fit starts from (``starts``: what of it)."""
    group.add_argument('--params', default=None, metavar='BASE.yaml',
                       help=f'terrain file to start from: {starts}; its other parameters are '
                       'copied to the output')


def add_report_arguments(group, report: str, plot: str) -> None:
    """Add ``--report OUT.json`` and ``--plot OUT.png`` (what each holds), then ``--force``."""
    group.add_argument('--report', default=None, metavar='OUT.json', help=report)
    group.add_argument('--plot', default=None, metavar='OUT.png', help=plot)
    add_force_argument(group)


def add_plot_output(outputs: Outputs, path, flag: str = '--plot') -> None:
    """
    Add a plot to the planned ``outputs`` when ``path`` is given, its format checked at once.

    matplotlib is imported only then: a run without a plot never loads it.

    Raises
    ------
    UsageError
        For a format matplotlib cannot write, before any work.

    """
    if path:
        from tracked_kinematics.offline.plots import check_format
        outputs.add(flag, path)
        check_format(flag, path)


def add_output_argument(parser) -> None:
    """Add ``--output``, the terrain file an identification tool writes."""
    parser.add_argument('--output', '-o', required=True, metavar='OUT.yaml',
                        help='terrain parameter file to write (ready for --params-file)')


def add_force_argument(parser) -> None:
    """Add ``--force``, the same flag on every tool (docs/output-files.md)."""
    parser.add_argument('--force', action='store_true',
                        help='replace output files that exist (never a directory, a bag, a '
                        'symbolic link or a special file)')


SPROCKET_RADIUS = bounded(0.005, 5.0, 'm')
TRACK_WIDTH = bounded(0.05, 20.0, 'm')
MIN_SPEED_RANGE = bounded(0.0, 20.0, 'm/s')
TICKS_PER_REVOLUTION = bounded(1.0, 1e9)


def add_imu_mount_argument(group, files: str) -> None:
    """Add ``--imu-mount ROLL PITCH YAW``: the IMU in base_link, as odometry_node's imu_mount.*."""
    group.add_argument('--imu-mount', type=bounded(-2.0 * math.pi, 2.0 * math.pi, 'rad'),
                       nargs=3, default=None, metavar=('ROLL', 'PITCH', 'YAW'),
                       help="the IMU's frame in base_link as a URDF joint's rpy, rad "
                       "(odometry_node's imu_mount.*; 3.14159 0 0: z down, or NED); the gyro "
                       f'is read as the node reads it. Default {files}, else 0 0 0')


#: s: odometry_node's range of ``imu_delay`` (a file with more would be refused there).
IMU_DELAY_RANGE = next((spec.low, spec.high) for spec in GYRO_PARAMS if spec.name == 'imu_delay')


def imu_delay(text: str):
    """Parse ``auto`` or a delay in :data:`IMU_DELAY_RANGE`, s."""
    if text == 'auto':
        return text
    return bounded(*IMU_DELAY_RANGE, 's')(text)


def add_imu_delay_argument(group) -> None:
    """Add ``--imu-delay auto|SECONDS``: the gyro's delay behind the encoders, given or auto."""
    group.add_argument('--imu-delay', type=imu_delay, default='auto', metavar='auto|SECONDS',
                       help='delay of the IMU stamps behind the encoders: auto estimates it '
                       '(refused where the tracks slip too much to time it: give the one '
                       'measured on firm ground)')


def add_sprocket_radius_argument(group) -> None:
    """Add ``--sprocket-radius``, defaulting to the base terrain file's (no other default)."""
    group.add_argument('--sprocket-radius', type=SPROCKET_RADIUS, default=None, metavar='R',
                       help='m; default from --params (required without it: there is no '
                       'default vehicle)')


def add_encoder_arguments(group) -> None:
    """Add the encoder options, named and defaulted as odometry_node's parameters."""
    defaults = EncoderSource()
    group.add_argument('--encoder-input', choices=INPUT_MODES, default=defaults.mode,
                       help='kind of encoder messages, as odometry_node input_mode')
    group.add_argument('--encoder-topic', default=defaults.topic,
                       help='sensor_msgs/JointState topic (joint_states)')
    group.add_argument('--left-joints', type=names, default=','.join(defaults.left_joints),
                       metavar='A,B', help='joints of the left track, averaged')
    group.add_argument('--right-joints', type=names, default=','.join(defaults.right_joints),
                       metavar='C,D', help='joints of the right track, averaged')
    group.add_argument('--left-topic', default=None,
                       help='left track topic: std_msgs/Float64 m/s (track_speeds) or '
                       'Int32/Int64 counter (encoder_ticks); default '
                       f'{" or ".join("/" + SIDE_TOPICS[m][0] for m in SIDE_TOPICS)}')
    group.add_argument('--right-topic', default=None, help='right track topic, likewise')
    group.add_argument('--ticks-per-revolution', type=TICKS_PER_REVOLUTION,
                       default=ENCODER_INPUT_DEFAULTS['ticks_per_revolution'],
                       help='encoder ticks per sprocket revolution (encoder_ticks)')


def encoder_settings(args) -> EncoderSource:
    """
    Build the encoder description from the options of :func:`add_encoder_arguments`.

    Unchecked, with the default sprocket radius: :func:`encoder_source` checks it and sets the
    radius.
    """
    side = SIDE_TOPICS.get(args.encoder_input)
    left, right = ('/' + side[0], '/' + side[1]) if side else ('', '')
    return EncoderSource(
        mode=args.encoder_input, topic=args.encoder_topic, left_joints=tuple(args.left_joints),
        right_joints=tuple(args.right_joints), left_topic=args.left_topic or left,
        right_topic=args.right_topic or right,
        ticks_per_revolution=args.ticks_per_revolution)


def encoder_source(args, radius: float) -> EncoderSource:
    """
    Build the encoder description from the options of :func:`add_encoder_arguments`.

    Raises
    ------
    UsageError
        When a joint is listed for both tracks.

    """
    return replace(checked_encoders(encoder_settings(args)), sprocket_radius=radius)


def write_report(path, report, force: bool = False) -> None:
    """Write a JSON report through :class:`~tracked_kinematics.offline.outputs.Outputs`."""
    with Outputs(force=force) as out:
        out.add('--report', path)
        out.write_text('--report', report_json(report))


def ground_truth_delay(text: str):
    """Argument type of ``--ground-truth-delay``: ``'auto'`` or a finite number of seconds."""
    if text == 'auto':
        return text
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'auto' or seconds, got {text!r}") from None
    if not math.isfinite(value) or abs(value) > 10.0:
        raise argparse.ArgumentTypeError(f'must be a finite number of seconds within +-10, '
                                         f'got {text}')
    return value


def add_ground_truth_topic_argument(parser, required: bool = True, extra: str = '') -> None:
    """Add ``--ground-truth-topic`` (required unless ``required`` is False)."""
    parser.add_argument('--ground-truth-topic', required=required, metavar='TOPIC',
                        help='ground-truth pose of the vehicle: Odometry, PoseStamped, '
                        'PoseWithCovarianceStamped or TFMessage' + extra)


def add_ground_truth_arguments(group, delay: bool = True) -> None:
    """
    Add the ground-truth options of identify_icr: frames, offset and (``delay``) its delay.

    ``--ground-truth-delay``: ``auto`` (default: estimated per bag) or seconds, 0 = none.
    """
    group.add_argument('--ground-truth-parent-frame', default='', metavar='FRAME',
                       help='TFMessage: fixed frame (default: the only parent of the child)')
    group.add_argument('--ground-truth-child-frame', default='base_link', metavar='FRAME',
                       help='TFMessage: the tracked frame')
    group.add_argument('--ground-truth-offset', type=bounded(-10.0, 10.0), nargs=3,
                       default=(0.0, 0.0, 0.0), metavar=('X', 'Y', 'YAW'),
                       help='pose of the tracked body in base_link (m, m, rad; each within '
                       '+-10)')
    if delay:
        group.add_argument('--ground-truth-delay', type=ground_truth_delay, default='auto',
                           metavar='auto|SECONDS',
                           help='delay of the ground-truth stamps behind the encoders (a pose '
                           'stamped on receipt): auto estimates it from the data, a number '
                           'fixes it, 0 turns the correction off')


def ground_truth_source(args) -> GroundTruthSource:
    """
    Build the ground-truth description from the options of :func:`add_ground_truth_arguments`.

    Raises
    ------
    UsageError
        For a non-finite offset.

    """
    offset = tuple(float(v) for v in args.ground_truth_offset)
    if not all(map(math.isfinite, offset)):
        raise UsageError(f'--ground-truth-offset must be finite, got {offset}')
    return GroundTruthSource(topic=args.ground_truth_topic,
                             parent_frame=args.ground_truth_parent_frame,
                             child_frame=args.ground_truth_child_frame, offset=offset)


def add_command_arguments(group, kinds=COMMAND_KINDS) -> None:
    """
    Add the command options: ``--command-source``, ``--setpoint-topics``, cmd_vel's topic.

    ``kinds``: the choices of ``--command-source`` (the first is the default).
    """
    group.add_argument('--command-source', choices=kinds, default=kinds[0],
                       help='setpoints (std_msgs/Float64 per track, m/s), cmd_vel (Twist or '
                       'TwistStamped, through the ideal inverse v -/+ w B/2 as a '
                       'diff_drive_controller base), auto (setpoints if the bag has them, '
                       'else cmd_vel)' + (', none' if 'none' in kinds else ''))
    group.add_argument('--setpoint-topics', type=topic_pair, default=','.join(SETPOINT_TOPICS),
                       metavar='LEFT,RIGHT', help='commanded track speeds, m/s')
    group.add_argument('--cmd-vel-topic', default=CMD_VEL_TOPIC, metavar='TOPIC',
                       help='commanded body twist (geometry_msgs/Twist or TwistStamped)')


def command_source(args, track_width: float | None) -> CommandSource:
    """Build the command description from the options of :func:`add_command_arguments`."""
    return CommandSource(args.command_source, tuple(args.setpoint_topics), args.cmd_vel_topic,
                         math.nan if track_width is None else float(track_width))


def write_together(outputs: Outputs, work, out) -> int:
    """
    Run ``work(outputs)``, write its outputs together at the end, and say where; return 0.

    An error in ``work`` leaves nothing (:class:`~tracked_kinematics.offline.outputs.Outputs`
    removes what it staged) and propagates to :func:`run_main`.
    """
    with outputs:
        work(outputs)
    print(f'wrote {", ".join(str(p) for p in outputs.targets)}', file=out)
    return 0


def run_main(prog: str, run, args) -> int:
    """
    Run ``run(args, sys.stdout)`` and map the package's errors to one stderr line and a status.

    :data:`EXIT_EXCITATION` for too little excitation, :data:`EXIT_FIT` for a fit that
    failed, :data:`EXIT_INPUT` for any other
    :class:`~tracked_kinematics.core.errors.TrackedKinematicsError` (a bag, option,
    parameter or output-path problem) and for an :class:`OSError` (a file the user named, a
    full disk), 130 for Ctrl-C, 143 for SIGTERM (129 for SIGHUP). Any other exception is a
    bug: it is not caught, and surfaces as a traceback.

    Signals (:mod:`tracked_kinematics.offline.signals`): the signal is raised as an
    exception, so that :class:`~tracked_kinematics.offline.outputs.Outputs` removes what the
    run staged, and whatever the run left staged is removed when it has ended
    (:func:`~tracked_kinematics.offline.outputs.abort_unfinished`); further signals are
    ignored until then (a second Ctrl-C cannot interrupt the clean-up), and so is one that
    arrives once the run's work has ended. A run inside a run (the demo runs its identify_icr
    step so) lets the signal's exception through to the outer one, which reports it.
    """
    outermost = signals.start()
    mark = begun()
    try:
        status, message = _run_mapped(run, args, outermost)
        if message is not None:
            message = error_line(prog, message)
    finally:
        if outermost:
            try:
                abort_unfinished(mark)
            finally:
                signals.finish()
    if message is not None:
        print(message, file=sys.stderr)
    return status


def _run_mapped(run, args, outermost: bool):
    """Run; return its status and error message (None), or those of the error it raised."""
    try:
        try:
            if outermost:
                signals.release()    # a signal since the process started ends the run here
            return run(args, sys.stdout), None
        finally:
            if outermost:
                signals.hold()
    except (TrackedKinematicsError, OSError) as err:
        return exit_status(err), err
    except KeyboardInterrupt:
        if not outermost:
            raise
        return signals.describe(signal.SIGINT)
    except Signalled as sig:
        if not outermost:
            raise
        return signals.describe(sig.signum)
