"""
The ``main`` of every node: arguments, init, construct, spin, shut down, exit status.

What a user sees at the edges of a node's life is decided here, once for the three nodes:

- ``--help`` / ``-h`` (before any ``--ros-args``) prints the usage, the parameters and the
  docs page, and exits 0 without starting ROS.
- Every start-up failure is one FATAL line naming the problem, exit status 2: a params file
  that is missing, a directory, not YAML, not a mapping or without ``ros__parameters``;
  arguments rcl refuses; invalid parameter values (:class:`ParameterError`); a topic or
  service name rclpy refuses; any other error while the node is built.
- Parameters a params file or ``-p`` sets that the node does not declare (a typo such as
  ``track_widht``) are named in a warning with the closest known name; ROS would ignore
  them silently.
- SIGINT and SIGTERM at any moment end the node cleanly with exit status 0: an error that a
  callback raises because the context was shut down under it is the shutdown, not a crash.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
import difflib
import os
import sys

import rclpy
from rclpy.executors import ExternalShutdownException
from tracked_kinematics.params import ParamSpec
from tracked_kinematics.ros.parameters import ParameterError
import yaml

EXIT_STARTUP = 2


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


def _option_values(ros_args: Sequence[str], *flags: str) -> list[str]:
    values = []
    for i, arg in enumerate(ros_args):
        if arg in flags and i + 1 < len(ros_args):
            values.append(ros_args[i + 1])
    return values


def params_file_keys(path: str, name: str) -> list[str]:
    """
    Check a ``--params-file`` the way rcl will read it; return the names it sets for ``name``.

    Raises
    ------
    StartupError
        When the file is missing, not a regular file, unreadable, not YAML, not a mapping,
        or has no ``ros__parameters`` section.

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
    sections = {key: section for key, section in doc.items()
                if isinstance(section, dict) and 'ros__parameters' in section}
    if not sections:
        raise StartupError(f'params file {path!r} has no "ros__parameters:" section (write '
                           f'"/**:\\n  ros__parameters:\\n    name: value")')
    keys = []
    for key, section in sections.items():
        node = str(key).lstrip('/').split('/')[-1]
        if node in ('**', '*', name):
            keys.extend(_flat_names(section['ros__parameters'] or {}))
    return keys


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
    One message per name in ``given`` that no spec declares, with the closest known name.

    ``use_sim_time`` and other parameters every rclpy node declares are known.
    """
    known = [spec.name for spec in specs] + ['use_sim_time', 'start_type_description_service']
    messages = []
    for name in dict.fromkeys(given):
        if name in known:
            continue
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
        hint = f' (did you mean {close[0]!r}?)' if close else ''
        messages.append(f'unknown parameter {name!r} ignored{hint}')
    return messages


def _usage(name: str, summary: str, specs: Sequence[ParamSpec]) -> str:
    lines = [f'usage: ros2 run tracked_kinematics {name} [--ros-args --params-file FILE '
             '-p NAME:=VALUE -r FROM:=TO ...]', '']
    if summary:
        lines += [summary.strip(), '']
    if specs:
        lines.append('parameters:')
        for spec in specs:
            lines.append(f'  {spec.name} (default {spec.default!r}): {spec.full_description}')
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
        start.

    """
    argv = list(sys.argv if args is None else args)
    user_args = argv[1:]
    plain = user_args[:user_args.index('--ros-args')] if '--ros-args' in user_args \
        else user_args
    if '--help' in plain or '-h' in plain:
        print(_usage(name, summary, specs))
        return 0
    logger = rclpy.logging.get_logger(name)
    ros_args = _ros_args(user_args)
    try:
        given = []
        for path in _option_values(ros_args, '--params-file'):
            given += params_file_keys(path, name)
        for value in _option_values(ros_args, '-p', '--param'):
            if ':=' not in value or not value.split(':=', 1)[0]:
                raise StartupError(f'-p needs NAME:=VALUE, got {value!r}')
            given.append(value.split(':=', 1)[0])
    except StartupError as err:
        logger.fatal(str(err))
        return EXIT_STARTUP
    try:
        rclpy.init(args=argv)
    except Exception as err:  # noqa: BLE001 -- rcl refuses arguments with RCLError
        logger.fatal(f'cannot start: {" ".join(str(err).split())}')
        return EXIT_STARTUP
    node = None
    try:
        try:
            node = node_factory()
        except ParameterError as err:
            logger.fatal(str(err))
            return EXIT_STARTUP
        except (KeyboardInterrupt, ExternalShutdownException):
            return 0
        except Exception as err:  # noqa: BLE001 -- any failure to start is one FATAL line
            if not rclpy.ok():  # a signal shut the context down while the node was built
                return 0
            logger.fatal(f'cannot start: {type(err).__name__}: {" ".join(str(err).split())}')
            return EXIT_STARTUP
        for message in unknown_parameters(given, specs):
            node.get_logger().warning(message)
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        # A callback that raced the shutdown (publisher's context invalid, ...) is part of
        # the shutdown; anything else while the context is still up is a real error.
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            try:
                node.destroy_node()
            except Exception:  # noqa: BLE001 -- destroying after a signal may fail; harmless
                pass
        try:
            rclpy.try_shutdown()
        except Exception:  # noqa: BLE001 -- raced rclpy's signal handler shutting it down
            pass
    return 0
