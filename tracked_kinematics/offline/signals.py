"""
Stop signals of the offline tools: a SIGINT, SIGTERM or SIGHUP at any instant ends a run cleanly.

A signal becomes an exception in the main thread, except inside held sections (:class:`held`)
and after the first stop; before a run begins it ends the process at once. What a user sees:
docs/output-files.md (rule 5).
"""

from __future__ import annotations

import atexit
import contextlib
import os
import signal
import sys
import threading

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

    Sections nest; the signal's exception is raised when the outermost ends (replacing the
    block's). Outside a run only Ctrl-C is held; no effect outside the main thread.
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
    """Act now, inside a held section, on a signal that arrived during it."""
    state = _state
    if _in_main_thread() and state.pending is not None and not state.stopping and (
            state.armed or state.borrowed):
        _stop(state.pending)


def install_for_tool(pending: list[int] | None = None) -> None:
    """
    Take the stop signals for the process of an offline tool, at its first import.

    Until :func:`start` a signal ends the process at once with its status and one line; at exit
    signals are ignored. ``pending``: signals that came while this module loaded (the first is
    acted on at once).
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
    Begin a run with signals held (:func:`release` lets them in); return whether it is outermost.

    A run inside a run (the demo's identify_icr), or outside the main thread, changes nothing.
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
    """End the outermost run: disarm, restore the handlers, drop a held signal."""
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
