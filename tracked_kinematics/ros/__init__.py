"""
The ROS ring: the nodes (rclpy), their parameter tables and their ``main``.

Signals at any moment
---------------------
A node's console script must end with status 0 and no traceback on SIGINT or SIGTERM,
whenever it comes. Two phases:

- Imports. Started as the console script of a node in :data:`QUIET_SIGNAL_NODES`, the
  process exits at once (``os._exit(0)``) on either signal from this package's first line
  on: the imports of the node's module (numpy, scipy, rclpy) take seconds on a loaded
  machine, nothing needs cleaning up yet, and an exception raised inside them is not safe
  (a C extension turns it into an ImportError traceback). A process that merely imports
  the package (the tests) keeps its handlers. The interpreter's own start-up, before this
  line runs (some 50 ms), is beyond any program's reach.
- Running. The node's ``main`` calls :func:`interrupt_on_signals` before ``run``: the first
  SIGINT or SIGTERM raises KeyboardInterrupt in the main thread, which ``run`` turns into a
  clean shutdown (rclpy chains its own handlers to this one after ``rclpy.init``, so a
  SIGTERM can no longer slip between rclpy's wake-up of the executor and its shutdown of
  the context and leave ``spin`` waiting forever); a second signal during that shutdown
  exits at once.
"""

import os as _os
import signal as _signal
import sys as _sys

#: Console scripts that exit quietly on SIGINT/SIGTERM from their first import on.
QUIET_SIGNAL_NODES = frozenset({'cmd_vel_translator'})

_SIGNALS = (_signal.SIGINT, _signal.SIGTERM)


def _exit_now(signum, frame):
    _os._exit(0)


def _interrupt(signum, frame):
    for sig in _SIGNALS:  # a second signal, during the shutdown: leave at once
        _signal.signal(sig, _exit_now)
    raise KeyboardInterrupt


def interrupt_on_signals() -> None:
    """Make the next SIGINT or SIGTERM a KeyboardInterrupt, and the one after an exit 0."""
    for sig in _SIGNALS:
        _signal.signal(sig, _interrupt)


def _console_script() -> str:
    main = _sys.modules.get('__main__')
    return _os.path.basename(getattr(main, '__file__', None) or '')


if _console_script() in QUIET_SIGNAL_NODES:
    for _sig in _SIGNALS:
        _signal.signal(_sig, _exit_now)
