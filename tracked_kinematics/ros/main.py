"""
The ``main`` of every node: arguments, init, construct, spin, shut down, exit status.

``--help`` without ROS; every start-up failure one FATAL line and status 2; misspelt
parameters refuse the start; a node that gave up exits 1; SIGINT/SIGTERM stop it cleanly with
0. See docs/nodes/odometry_node.md ("Start-up and shutdown") and docs/testing.md.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
import contextlib
import os
import signal
import sys
import threading

import rclpy
import rclpy.executors
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerOptions
from tracked_kinematics import params, ros
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.params import ParamSpec, read_params_file
from tracked_kinematics.params.dimensions import dimension_conflicts, DIMENSION_KEYS
from tracked_kinematics.params.tables import is_terrain_file_record
from tracked_kinematics.ros.parameters import (NODE_PARAMETERS, package_parameter_names,
                                               package_parameters, ParameterError)
import yaml

EXIT_STARTUP = 2
EXIT_FAILURE = 1
STOP_POLL_PERIOD = 0.05  # s: how soon the main thread sees a signal's stop request
JOIN_TIMEOUT = 5.0  # s: how long a running callback may delay the shutdown


class StartupError(Exception):
    """A problem with the node's arguments found before ROS starts; one line for the user."""


def _ros_args(argv: Sequence[str]) -> list[str]:
    """Return the arguments inside ``--ros-args ... [--]`` sections."""
    inside, out = False, []
    for arg in argv:
        if arg == '--ros-args':
            inside = True
        elif arg == '--' and inside:
            inside = False
        elif inside:
            out.append(arg)
    return out


def params_file_sections(path: str) -> list[tuple[str, list[str]]]:
    """
    Check a ``--params-file`` as rcl will read it; return ``[(node, names set)]`` per section.

    The node is the last part of the section's key (``**``, ``*`` or a name), in file order.
    Raises :class:`StartupError` for a missing, unreadable or non-YAML file, or one that is not
    a mapping or has no ``ros__parameters`` section.
    """
    if not os.path.exists(path):
        raise StartupError(f'params file {path!r} does not exist')
    if not os.path.isfile(path):
        raise StartupError(f'params file {path!r} is not a regular file')
    try:
        with open(path, encoding='utf-8') as stream:
            doc = yaml.safe_load(stream)
    except OSError as err:
        raise StartupError(f'params file {path!r} cannot be read: {err.strerror}') from None
    except (yaml.YAMLError, UnicodeDecodeError) as err:
        raise StartupError(
            f'params file {path!r} is not valid YAML: {" ".join(str(err).split())}') from None
    if not isinstance(doc, dict):
        raise StartupError(f'params file {path!r} is not a mapping of node names to '
                           '"ros__parameters:" sections')
    sections = [(str(key).lstrip('/').split('/')[-1],
                 list(_flat_names(section['ros__parameters'] or {})))
                for key, section in doc.items()
                if isinstance(section, dict) and 'ros__parameters' in section]
    if not sections:
        raise StartupError(f'params file {path!r} has no "ros__parameters:" section (write '
                           f'"/**:\\n  ros__parameters:\\n    name: value")')
    return sections


def params_file_keys(path: str, name: str) -> list[str]:
    """Check a ``--params-file`` (:func:`params_file_sections`); return its names for ``name``."""
    return [key for node, keys in params_file_sections(path) if node in ('**', '*', name)
            for key in keys]


def dimension_sources(name: str, ros_args: Sequence[str]) -> list[tuple[str, dict]]:
    """
    Return where the command line gives the vehicle's dimensions, for :func:`dimension_conflicts`.

    One source per ``--params-file`` (its ``/**`` section and the node's own, as rcl reads it)
    and per ``-p`` of a :data:`~tracked_kinematics.params.dimensions.DIMENSION_KEYS` name, in
    command-line order. A file that cannot be read is passed over (its own check names it).
    """
    sources = []
    for i, arg in enumerate(ros_args[:-1]):
        value = ros_args[i + 1]
        if arg == '--params-file':
            try:
                sources.append((f'params file {value}', read_params_file(value, name)))
            except (InvalidParameters, OSError):
                continue
        elif arg in ('-p', '--param') and ':=' in value:
            key, text = value.split(':=', 1)
            if key in DIMENSION_KEYS:
                try:
                    sources.append((f'-p {value}', {key: yaml.safe_load(text)}))
                except yaml.YAMLError:
                    continue
    return sources


def _flat_names(tree, prefix: str = '') -> Iterable[str]:
    if not isinstance(tree, dict):
        return
    for key, value in tree.items():
        full = f'{prefix}{key}'
        if isinstance(value, dict):
            yield from _flat_names(value, full + '.')
        else:
            yield full


def unknown_parameters(given: Iterable[str], specs: Iterable[ParamSpec]) -> list[str]:
    """
    Return one message per name in ``given`` that no node of this package declares.

    rclpy's own parameters and the records the tools write into a terrain file
    (``identification.*``, ``terrain``) are passed over.
    """
    specs = list(specs)
    own = {spec.name for spec in specs}
    others = package_parameter_names() - own
    return params.unknown_parameters(
        [name for name in given if not is_terrain_file_record(name) and name not in others],
        [*specs, *NODE_PARAMETERS])


def normalised_arguments(argv: Sequence[str]) -> list[str]:
    """Return ``argv`` with ``-p NAME:=`` (the shell's ``-p NAME:=''``) as ``-p NAME:=''``."""
    out, inside, after_p = [], False, False
    for arg in argv:
        if arg == '--ros-args':
            inside = True
        elif arg == '--' and inside:
            inside = False
        elif inside and after_p and arg.endswith(':=') and arg.count(':=') == 1 \
                and len(arg) > 2:
            arg += "''"
        after_p = inside and arg in ('-p', '--param')
        out.append(arg)
    return out


def _settings_notices(name: str, specs: Sequence[ParamSpec], settings) -> list[str]:
    """
    Return warnings about values a user set that this node will not use.

    ``settings``: ``('file', path, sections)`` per ``--params-file`` and ``('p', NAME)`` per
    ``-p``, in command-line order.
    """
    own = {spec.name: spec for spec in specs}
    mine = ('**', '*', name)
    notices = []
    for i, item in enumerate(settings):
        if item[0] != 'p' or item[1] not in own:
            continue
        for j, (kind, *rest) in enumerate(settings):
            if kind != 'file':
                continue
            path, sections = rest
            for node, keys in sections:
                if item[1] not in keys:
                    continue
                if node == name:
                    notices.append(
                        f'-p {item[1]} has no effect: the section {node!r} of {path} sets it, '
                        'and rcl gives a section naming the node precedence over -p; change '
                        'it in the file, or move it under /**')
                elif node in mine and j > i:
                    notices.append(f'-p {item[1]} has no effect: {path}, given after it, sets '
                                   'it too (the last one wins)')
    given = {key for kind, *rest in settings if kind == 'file'
             for node, keys in rest[1] if node in mine for key in keys}
    given |= {item[1] for item in settings if item[0] == 'p'}
    nodes = package_parameters()
    for kind, *rest in settings:
        if kind != 'file':
            continue
        path, sections = rest
        for node, keys in sections:
            if node in mine or node not in nodes:
                continue
            theirs = {spec.name: spec for spec in nodes[node]}
            shared = [key for key in keys if key not in given and key in own
                      and theirs.get(key) == own[key]]
            if shared:
                notices.append(
                    f'{path} sets {", ".join(shared)} only for {node}; {name} uses '
                    f'{"its default" if len(shared) == 1 else "their defaults"} unless given: '
                    'put what every node shares under /** (convert_diff_drive_params writes '
                    'it so)')
                given.update(shared)
    return notices


def _usage(name: str, summary: str, specs: Sequence[ParamSpec]) -> str:
    lines = [f'usage: ros2 run tracked_kinematics {name} [--ros-args --params-file FILE '
             '-p NAME:=VALUE -r FROM:=TO ...]', '']
    if summary:
        lines += [summary.strip(), '']
    if specs:
        lines.append('parameters:')
        for spec in specs:
            unit = f' [{spec.unit}]' if spec.unit else ''
            lines.append(f'  {spec.name} ({spec.default_text}): {spec.description}{unit}')
        lines.append('')
    lines.append(f'Reference: docs/nodes/{name}.md (parameters: docs/parameters.md).')
    return '\n'.join(lines)


def run(node_factory: Callable[[], 'rclpy.node.Node'], name: str, args=None,
        specs: Sequence[ParamSpec] = (), summary: str = '') -> int:
    """
    Run one node until shutdown; return the process exit status.

    Parameters
    ----------
    node_factory : callable
        Builds the node (after ``rclpy.init``).
    name : str
        Node and executable name (logger name when the node could not be built).
    args : list of str, optional
        The command line as ``sys.argv`` has it (program name first), the default.
    specs : sequence of ParamSpec
        The node's parameters, for ``--help`` and the unknown-parameter warning.
    summary : str
        What the node does, for ``--help``.

    Returns
    -------
    int
        0 after a normal or signalled shutdown, :data:`EXIT_STARTUP` when the node could not
        start, :data:`EXIT_FAILURE` when it gave up (its ``failure`` attribute is set).

    """
    argv = normalised_arguments(sys.argv if args is None else args)
    user_args = argv[1:]
    plain = user_args[:user_args.index('--ros-args')] if '--ros-args' in user_args \
        else user_args
    if '--help' in plain or '-h' in plain:
        print(_usage(name, summary, specs))
        return 0
    built = []

    def build():
        built.append(node_factory())
        return built[-1]

    stop = StopRequest()
    with stop.installed():
        status = _run(build, name, user_args, argv, specs, stop)
    if status == 0 and built and getattr(built[0], 'failure', None) is not None:
        return EXIT_FAILURE
    return status


class StopRequest:
    """
    SIGINT and SIGTERM as a request to stop, acted upon by the main thread in its own time.

    The handler only sets a flag (no lock, no rclpy call); rclpy's handlers are not installed.
    """

    def __init__(self) -> None:
        self.signum: int | None = None

    @property
    def requested(self) -> bool:
        """Return whether a signal asked the node to stop."""
        return self.signum is not None

    def _handle(self, signum, frame) -> None:
        self.signum = signum

    @contextlib.contextmanager
    def installed(self):
        """Handle SIGINT and SIGTERM while the block runs (main thread only)."""
        with _signal_handlers(self._handle):
            yield self


def _run(node_factory, name, user_args, argv, specs, stop: StopRequest) -> int:
    logger = rclpy.logging.get_logger(name)
    ros_args = _ros_args(user_args)
    settings = []
    try:
        for i, arg in enumerate(ros_args[:-1]):
            value = ros_args[i + 1]
            if arg == '--params-file':
                settings.append(('file', value, params_file_sections(value)))
            elif arg in ('-p', '--param'):
                if ':=' not in value or not value.split(':=', 1)[0]:
                    raise StartupError(f'-p needs NAME:=VALUE, got {value!r}')
                settings.append(('p', value.split(':=', 1)[0]))
        conflicts = dimension_conflicts(dimension_sources(name, ros_args))
        if conflicts:
            raise StartupError('; '.join(conflicts))
    except StartupError as err:
        logger.fatal(str(err))
        return EXIT_STARTUP
    given = [key for kind, *rest in settings if kind == 'file'
             for node, keys in rest[1] if node in ('**', '*', name) for key in keys]
    given += [item[1] for item in settings if item[0] == 'p']
    if stop.requested:
        return 0
    try:
        rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as err:  # noqa: BLE001 -- rcl refuses arguments with RCLError
        logger.fatal(f'cannot start: {" ".join(str(err).split())}')
        return EXIT_STARTUP
    for notice in _settings_notices(name, specs, settings):
        logger.warning(notice)
    node = None
    try:
        try:
            node = node_factory()
        except ParameterError as err:
            logger.fatal(str(err))
            return EXIT_STARTUP
        except ExternalShutdownException:
            return 0
        except Exception as err:  # noqa: BLE001 -- any failure to start is one FATAL line
            if not rclpy.ok():
                return 0  # the node shut the context down while it was being built
            logger.fatal(f'cannot start: {type(err).__name__}: {" ".join(str(err).split())}')
            return EXIT_STARTUP
        if stop.requested:
            return 0
        for message in unknown_parameters(given, specs):
            node.get_logger().warning(message)
        _spin_until_stopped(node, stop)
    finally:
        error = None
        if node is not None:  # the node first, then its context
            try:
                node.destroy_node()
            except Exception as err:  # noqa: BLE001 -- a node that shut its context down
                error = err if rclpy.ok() else None
        try:
            rclpy.try_shutdown()
        except Exception:  # noqa: BLE001 -- a node's own shutdown may have raced this one
            pass
        if error is not None:
            raise error
    return 0


def _spin_until_stopped(node, stop: StopRequest) -> None:
    """Spin ``node`` in a thread until stopped; re-raise a callback's error."""
    executor = rclpy.executors.SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    done = threading.Event()
    state = {'stopping': False, 'error': None}

    def spin() -> None:
        try:
            while not state['stopping'] and node.context.ok():
                executor.spin_once()
        except ExternalShutdownException:
            pass
        except BaseException as err:  # noqa: BLE001 -- handed to the main thread
            if node.context.ok():
                state['error'] = err
        finally:
            done.set()

    thread = threading.Thread(target=spin, name=f'{node.get_name()}_executor', daemon=True)
    thread.start()
    try:
        while not stop.requested and not done.wait(STOP_POLL_PERIOD):
            pass
    finally:
        state['stopping'] = True
        # A shut-down executor leaves its wait at once; a woken one waits again for work
        # (rclpy rebuilds the wait set), which never comes to a node with no traffic (the
        # simulator without setpoints held the stop 5 s that way).
        executor.shutdown(timeout_sec=0)
        thread.join(JOIN_TIMEOUT)
        if thread.is_alive():  # a callback that does not return: the shutdown will end it
            node.get_logger().warning(
                f'a callback is still running {JOIN_TIMEOUT:g} s after the stop request; '
                'shutting down under it')
            rclpy.try_shutdown(context=node.context)
            thread.join(JOIN_TIMEOUT)
        executor.shutdown(timeout_sec=0)
    if state['error'] is not None:
        raise state['error']


_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def _signal_handlers(handler):
    """Install ``handler`` for SIGINT and SIGTERM (main thread only), restore on exit."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.getsignal(sig) for sig in _SIGNALS}
    for sig in _SIGNALS:
        signal.signal(sig, handler)
    try:
        yield
    finally:
        for sig, old in previous.items():
            # A node's console script is about to exit: a late signal (a second Ctrl-C, a
            # SIGTERM during the interpreter's finalisation, where Python resets its own
            # handlers to the default action) is ignored rather than let kill the process.
            signal.signal(sig, signal.SIG_IGN if old is ros.exit_quietly else old)
