"""
Stop signals of the offline tools: a SIGINT, SIGTERM or SIGHUP at any instant ends a run cleanly.

A signal becomes an exception in the main thread (KeyboardInterrupt for SIGINT,
:class:`Signalled` for SIGTERM and SIGHUP), so that the run unwinds and
:class:`~tracked_kinematics.offline.outputs.Outputs` removes what it staged. An exception can
land between any two bytecodes, though, and some steps must not be cut in half: creating a
temporary file and taking charge of it, renaming the outputs onto their targets, removing
them again. Four rules keep a signal from landing there:

- **held sections** (:class:`held`): those steps run with the stop signals held. One that
  arrives meanwhile is recorded and acted on when the outermost section ends, where the
  state is whole again;
- **one stop per run**: once a run has acted on a signal, later ones are ignored, so that an
  impatient second Ctrl-C cannot interrupt the clean-up;
- **the whole process**: when a console script of the offline tools starts, the package's
  ``__init__`` (``tracked_kinematics/__init__.py``, its first line of code) calls
  :func:`install_for_tool`, before numpy, scipy and rosbags are imported (the better part
  of a second). A signal during the imports or the parsing of the options,
  before :func:`~tracked_kinematics.offline.cli.common.run_main` has begun and so before
  anything can have been written, ends the process at once with the signal's exit status
  and the one line; once the run has ended, signals are ignored, so that the process exits
  with the run's status and cannot be killed half-way through the interpreter's shutdown;
- **outside a run** (a Python program calling the library), a held section holds Ctrl-C the
  same way and raises the KeyboardInterrupt at its end; other signals keep their handlers.

Only the main thread is affected: signals are handled there, and a section held by another
thread holds nothing.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import signal
import sys
import threading

from tracked_kinematics import TOOL_EXECUTABLES  # noqa: F401 -- the tools' names

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""The signals that end a run: 130 (SIGINT), 143 (SIGTERM), 129 (SIGHUP)."""


class Signalled(BaseException):
    """SIGTERM or SIGHUP arrived; raised in the main thread so that outputs are cleaned up."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


class _State:
    """What the handler needs to know; changed only in the main thread."""

    __slots__ = ('held', 'pending', 'stopping', 'armed', 'tool', 'started', 'borrowed',
                 'previous')

    def __init__(self):
        self.held = 0            # depth of held sections
        self.pending = None      # a signal not acted on yet
        self.stopping = False    # the run has acted on a signal: ignore further ones
        self.armed = False       # a run (run_main) is under way: act on signals
        self.tool = False        # this process is a console script of the offline tools
        self.started = False     # ... and its run has begun: it may have written something
        self.borrowed = False    # SIGINT's default handler replaced for a held section
        self.previous = {}       # handlers before run_main (in-process runs restore them)


_state = _State()


def _in_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def _on_signal(signum, frame):
    state = _state
    if state.stopping or state.pending is not None:
        return                   # the run is stopping already, or will at once
    if state.tool and not state.started and not state.held:
        _exit_now(signum)        # the tool is starting: nothing can have been written yet
    if state.armed and not state.held:
        _stop(signum)
    state.pending = signum       # acted on when the held section ends, or the run begins


def describe(signum: int) -> tuple[int, str]:
    """Return the exit status and the reason a stop signal ends a run with (130, 'interrupted')."""
    if signum == signal.SIGINT:
        return 130, 'interrupted'
    return 128 + signum, f'terminated by {signal.Signals(signum).name}'


def _exit_now(signum: int):
    status, reason = describe(signum)
    prog = os.path.basename(sys.argv[0] if sys.argv else '') or 'tracked_kinematics'
    with contextlib.suppress(OSError):    # no stderr: the status says it
        os.write(2, f'{prog}: error: {reason}\n'.encode())
    os._exit(status)


def _stop(signum: int):
    """Act on ``signum``: raise its exception; in a run, the only one it acts on."""
    state = _state
    state.pending = None
    if state.armed:
        state.stopping = True
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Signalled(signum)


def _hold() -> None:
    _state.held += 1


def _release() -> None:
    state = _state
    state.held -= 1
    if not state.held and state.pending is not None and state.armed and not state.stopping:
        _stop(state.pending)


class held:
    """
    Context manager: hold SIGINT, SIGTERM and SIGHUP for the block; act on one at its end.

    For steps that must complete once begun: create a temporary file and take charge of it,
    rename the outputs, remove them. Sections nest; a signal that arrived during the block
    raises its exception when the outermost one ends (when the block raised, the signal's
    exception replaces its exception). Outside a run, only Ctrl-C with Python's default
    handler is held. No effect outside the main thread.
    """

    __slots__ = ('_main',)

    def __enter__(self):
        """Hold the signals."""
        self._main = _in_main_thread()
        if self._main:
            state = _state
            if not (state.held or state.armed or state.tool or state.borrowed) and \
                    signal.getsignal(signal.SIGINT) is signal.default_int_handler:
                signal.signal(signal.SIGINT, _on_signal)
                state.borrowed = True
            _hold()
        return self

    def __exit__(self, *exc):
        """Release them; raise the exception of one that arrived."""
        if not self._main:
            return False
        state = _state
        if state.borrowed and state.held == 1:
            state.held = 0
            signal.signal(signal.SIGINT, signal.default_int_handler)
            state.borrowed = False
            if state.pending is not None:
                _stop(state.pending)
            return False
        _release()
        return False


def raise_pending() -> None:
    """
    Act now, inside a held section, on a signal that arrived during it.

    For a point of a held section where unwinding is safe and better than going on (the
    commit, before the first rename).
    """
    state = _state
    if _in_main_thread() and state.pending is not None and not state.stopping and (
            state.armed or state.borrowed):
        _stop(state.pending)


def install_for_tool(pending: list[int] | None = None) -> None:
    """
    Take the stop signals for the process of an offline tool, at its first import.

    Until the run begins (:func:`start`), a signal ends the process at once with its status
    and one line: nothing has been written. At exit they are ignored, so that the
    interpreter's shutdown cannot be killed half-way. ``pending``: a signal that came while
    this module was loading (the package's ``__init__`` collects them until the handler
    here is installed, and may append to the list until then), the first acted on at once.
    """
    if not _in_main_thread() or _state.tool:
        return
    _state.tool = True
    for signum in STOP_SIGNALS:
        signal.signal(signum, _on_signal)
    atexit.register(_ignore_signals)
    if pending:
        _exit_now(pending[0])


def _ignore_signals() -> None:
    if _in_main_thread():
        for signum in STOP_SIGNALS:
            signal.signal(signum, signal.SIG_IGN)


def start() -> bool:
    """
    Begin a run (:func:`~tracked_kinematics.offline.cli.common.run_main`), signals held.

    Installs the handler and holds the signals; :func:`release` lets them interrupt the run.
    Return whether this is the outermost run of the process (a run inside a run, as the demo
    runs identify_icr, leaves the signals to the outer one and changes nothing here; so does
    a run outside the main thread).
    """
    state = _state
    if not _in_main_thread() or state.armed:
        return False
    _hold()
    state.started = True
    handlers = {signum: signal.signal(signum, _on_signal) for signum in STOP_SIGNALS}
    if not state.tool:
        state.previous = handlers
        state.pending = None
    state.stopping = False
    state.armed = True
    return True


def release() -> None:
    """Let a signal interrupt the run from here on; act at once on one that came before."""
    _release()


def hold() -> None:
    """Hold the signals again once the run's work has ended (its errors are being reported)."""
    _hold()


def finish() -> None:
    """
    End the outermost run: disarm, and restore the handlers (ignore signals in a tool).

    A signal held since the run's work ended is dropped: the run is over, its outputs are
    as it left them.
    """
    state = _state
    state.armed = False
    if state.tool:
        _ignore_signals()
    else:
        for signum, handler in state.previous.items():
            signal.signal(signum, handler)
        state.previous = {}
    state.held = 0
    state.pending = None
    state.stopping = False
