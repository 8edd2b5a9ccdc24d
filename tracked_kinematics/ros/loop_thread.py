"""
A node's own loop in a thread: stopped with the node or its context, alive through errors.

Used by cmd_vel_translator and tracked_simulator, paced on the steady clock. Errors are logged
(throttled); passes failing for :data:`FAILURE_LIMIT` s make the node give up (one FATAL
line, exit status 1).
"""

from __future__ import annotations

from collections.abc import Callable
import threading
import time

from tracked_kinematics.ros.parameters import TableNode

FAILURE_LIMIT = 1.0  # s of failing passes after which the node stops
JOIN_TIMEOUT = 5.0  # s the node waits for the loop to end when it is destroyed


class LoopThread:
    """
    The thread of a node's loop, its stop and wake events, and its failure accounting.

    ``target`` runs until :attr:`stop` is set; :attr:`wake` cuts its waits short. It calls
    :meth:`succeeded` after each good pass and :meth:`failed` after each bad one.

    Parameters
    ----------
    what : str
        What a pass does, as logged: ``f'{what} failed: ...'`` (throttled by ``warn_period`` s).
    giving_up : str
        The same for the FATAL line: ``f'{giving_up} has failed for 1 s (last error: ...)'``.

    Attributes
    ----------
    failure : Exception or None
        The last error, once the loop gave up and shut the context down.

    """

    def __init__(self, node, target: Callable[[], None], name: str, what: str,
                 giving_up: str, warn_period: float):
        self._node = node
        self._what = what
        self._giving_up = giving_up
        self._warn_period = warn_period
        self.stop = threading.Event()
        self.wake = threading.Event()
        self.failure: Exception | None = None
        self._failing_since: float | None = None
        node.context.on_shutdown(self.request_stop)
        self._thread = threading.Thread(target=target, name=name, daemon=True)

    def start(self) -> None:
        """Start the loop."""
        self._thread.start()

    def request_stop(self) -> None:
        """Ask the loop to end (and wake it to see that)."""
        self.stop.set()
        self.wake.set()

    def join(self) -> None:
        """Stop the loop and wait (up to :data:`JOIN_TIMEOUT`) until it has ended."""
        self.request_stop()
        thread = self._thread
        if thread.is_alive() and thread is not threading.current_thread():
            thread.join(JOIN_TIMEOUT)

    def succeeded(self) -> None:
        """Note a good pass: failures are counted again from the next one."""
        self._failing_since = None

    def failed(self, err: Exception) -> bool:
        """Handle the error of a pass; return whether the loop is to end (stopped, or given up)."""
        node = self._node
        if self.stop.is_set() or not node.context.ok():
            return True
        now = time.monotonic()
        if self._failing_since is None:
            self._failing_since = now
        if now - self._failing_since >= FAILURE_LIMIT:
            self._give_up(err)
            return True
        node.get_logger().error(f'{self._what} failed: {err!r}',
                                throttle_duration_sec=self._warn_period)
        return False

    def _give_up(self, err: Exception) -> None:
        self.failure = err
        node = self._node
        node.get_logger().fatal(
            f'{self._giving_up} has failed for {FAILURE_LIMIT:g} s (last error: {err!r}): '
            'stopping the node')
        try:
            node.context.try_shutdown()
        except Exception:  # noqa: BLE001 -- shutting down anyway
            pass


class LoopNode(TableNode):
    """
    A :class:`~tracked_kinematics.ros.parameters.TableNode` with a loop thread of its own.

    The subclass starts it in ``_start`` (:meth:`_start_loop`); it is stopped before the node is
    destroyed. ``failure``: why the loop gave up, if it did (the console script exits 1).
    """

    _loop_thread: LoopThread | None = None

    def _start_loop(self, target: Callable[[], None], name: str, what: str, giving_up: str,
                    warn_period: float) -> None:
        """Start the node's loop (:class:`LoopThread` arguments) as ``_loop_thread``."""
        self._loop_thread = LoopThread(self, target, name, what, giving_up, warn_period)
        self._loop_thread.start()

    @property
    def failure(self) -> Exception | None:
        """Return why the loop gave up and stopped the node, if it did."""
        return None if self._loop_thread is None else self._loop_thread.failure

    def _stop_loop(self) -> None:
        if self._loop_thread is not None:
            self._loop_thread.join()

    def _abandon(self) -> None:
        self._stop_loop()

    def destroy_node(self):
        """Stop the loop, then destroy the node."""
        self._stop_loop()
        super().destroy_node()
