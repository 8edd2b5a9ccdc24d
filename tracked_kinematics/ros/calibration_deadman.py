"""
calibration_deadman: hold calibration_drive's deadman from the keyboard and show its status.

The space bar (held, via auto-repeat) publishes ``true`` on ``deadman`` at 20 Hz, any other
key ``false``; ``--hold`` holds it without a keyboard. Ends when the drive is done.
See docs/nodes/calibration_deadman.md.
"""

from __future__ import annotations

import argparse
import json
import os
import select
import sys
import termios
import threading
import time
import tty

from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool, String
from std_srvs.srv import Trigger
from tracked_kinematics.ros.input_topic import steady_timer
from tracked_kinematics.ros.main import run

NODE_NAME = 'calibration_deadman'
HOLD_KEY = ' '
#: Longest auto-repeat delay of a terminal (the X server's default is 0.66 s), s.
FIRST_REPEAT = 0.8
#: Let go: no repeat for this many repeat intervals (at least RELEASE_MIN s).
RELEASE_REPEATS = 3.0
RELEASE_MIN = 0.15
#: After the drive latched a stale deadman, --hold lets go this long, then presses again, s.
REPRESS = 0.3
#: --hold publishes false this long after a subscriber appears, so the drive sees a press
#: (a false, then true).
PRESS_AFTER = 0.5


class KeyHold:
    """A key held down, as a terminal shows it: one press, then auto-repeats."""

    def __init__(self) -> None:
        self._last: float | None = None
        self._interval: float | None = None

    def press(self, t: float) -> None:
        """Record that the key went down (or auto-repeated) at ``t``, s."""
        if self._last is not None:
            gap = t - self._last
            self._interval = gap if self._interval is None else min(self._interval, gap)
        self._last = t

    def release(self) -> None:
        """Let go at once (another key was pressed)."""
        self._last = self._interval = None

    def held(self, t: float) -> bool:
        """Return whether the key is held at ``t``: released when its repeats stop."""
        if self._last is None:
            return False
        limit = FIRST_REPEAT if self._interval is None else max(
            RELEASE_MIN, RELEASE_REPEATS * self._interval)
        if t - self._last > limit:
            self.release()
            return False
        return True


def status_line(status: dict) -> str:
    """Return the one line shown for a status message of calibration_drive."""
    parts = [status.get('state', '?')]
    if status.get('reason'):
        parts.append(f'({status["reason"]})')
    if status.get('steps'):
        parts.append(f'step {min(status.get("step", 0) + 1, status["steps"])}/{status["steps"]}'
                     + (f' {status["step_kind"]}' if status.get('step_kind') else ''))
    if status.get('distance') is not None:
        parts.append(f'{status["distance"]:.2f} m from the centre')
    if status.get('phase') not in (None, 'drive'):
        parts.append(f'[{status["phase"]}]')
    if status.get('exit_status') is not None:
        parts.append(f'exit status {status["exit_status"]}')
    return ' '.join(parts)


class DeadmanNode(Node):
    """Publish the deadman at ``rate``; print the drive's status; end when the drive is done."""

    def __init__(self, options, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self._options = options
        self._hold = KeyHold()
        self._matched: float | None = None   # when a subscriber first appeared
        self._repress_until = 0.0             # --hold lets go until then (a new press)
        self._lock = threading.Lock()
        self._shown = None
        self._start_client = None
        self._started = False
        self.done_status: int | None = None
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self._pub = self.create_publisher(Bool, options.topic, 10)
        drive = options.drive.rstrip('/')
        self.create_subscription(String, f'{drive}/status', self._on_status, reliable)
        if options.start:
            self._start_client = self.create_client(Trigger, f'{drive}/start')
        self._timer = steady_timer(self, 1.0 / options.rate, self._on_timer)
        how = ('held while this runs (--hold)' if options.hold
               else 'hold the space bar; let go (or any other key) to release')
        self.get_logger().info(f'deadman on {self._pub.topic_name} at {options.rate:g} Hz: '
                               f'{how}; status of {drive}')

    def key(self, char: str, t: float) -> None:
        """Take a key the terminal delivered at ``t`` (the keyboard thread calls this)."""
        with self._lock:
            if char == HOLD_KEY:
                self._hold.press(t)
            else:
                self._hold.release()

    def held(self) -> bool:
        """Return whether the deadman is held now."""
        now = time.monotonic()
        if self.done_status is not None:
            return False
        if self._options.hold:
            if self._matched is None and self._pub.get_subscription_count() > 0:
                self._matched = now
            return self._matched is not None and now - self._matched >= PRESS_AFTER \
                and now >= self._repress_until
        with self._lock:
            return self._hold.held(now)

    def _on_timer(self) -> None:
        held = self.held()
        self._pub.publish(Bool(data=held))
        if held and self._start_client is not None and not self._started \
                and self._start_client.service_is_ready():
            self._started = True
            self._start_client.call_async(Trigger.Request()).add_done_callback(self._on_start)

    def _on_start(self, future) -> None:
        result = future.result()
        print(f'start: {result.message if result is not None else "no answer"}', flush=True)

    def _on_status(self, msg: String) -> None:
        try:
            status = json.loads(msg.data)
        except ValueError:
            return
        if not isinstance(status, dict):
            return
        line = status_line(status)
        if line != self._shown:
            self._shown = line
            print(line, flush=True)
            reason = str(status.get('reason', ''))
            if self._options.hold and status.get('state') == 'paused' and (
                    'stale' in reason or 'not held within' in reason):
                # The drive latched a deadman that went stale (a hiccup of this process or
                # of the link): like a person, --hold lets go and presses again.
                print('the deadman went stale: pressing it again (--hold)', flush=True)
                self._repress_until = time.monotonic() + REPRESS
        if status.get('exit_status') is not None and self.done_status is None:
            self.done_status = int(status['exit_status'])
            self._pub.publish(Bool(data=False))
            # Delivered before the context goes (a shutdown drops what is in flight).
            self._pub.wait_for_all_acked(Duration(seconds=1.0))
            print(f'calibration drive done (exit status {self.done_status})', flush=True)
            self.context.try_shutdown()

    def destroy_node(self):
        """Release the deadman, then destroy the node."""
        try:
            self._pub.publish(Bool(data=False))
        except Exception:  # noqa: BLE001 -- the context is already gone: nothing to send
            pass
        return super().destroy_node()


def _read_keys(node: DeadmanNode, stop: threading.Event) -> None:
    """Hand every key typed on stdin to ``node`` until ``stop`` is set."""
    fd = sys.stdin.fileno()
    while not stop.is_set():
        ready, _, _ = select.select([fd], [], [], 0.05)
        if ready:
            data = os.read(fd, 64)
            if not data:
                return
            t = time.monotonic()
            for char in data.decode(errors='replace'):
                node.key(char, t)


def build_parser() -> argparse.ArgumentParser:
    """Return the tool's argument parser (the options before ``--ros-args``)."""
    parser = argparse.ArgumentParser(
        prog=NODE_NAME, description=__doc__.strip().splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument('--hold', action='store_true',
                        help='hold the deadman as long as this runs, without a keyboard (the '
                             'simulator, scripts); on a robot, hold a real button instead')
    parser.add_argument('--start', action='store_true',
                        help="call the drive's ~/start once the deadman is held")
    parser.add_argument('--topic', default='deadman', help='deadman topic (std_msgs/Bool)')
    parser.add_argument('--drive', default='/calibration_drive',
                        help='the calibration_drive node (its status and start service)')
    parser.add_argument('--rate', type=float, default=20.0, help='publish rate, Hz')
    return parser


def parse(argv):
    """Split ``argv`` into this tool's options and the arguments for ROS (program first)."""
    args = list(argv[1:])
    ros = args[args.index('--ros-args'):] if '--ros-args' in args else []
    parser = build_parser()
    options = parser.parse_args(args[:len(args) - len(ros)])
    if not 1.0 <= options.rate <= 1000.0:
        parser.error(f'--rate must be in [1, 1000] Hz, got {options.rate:g}')
    return options, [argv[0], *ros]


def main(args=None):
    """Run calibration_deadman (console script ``calibration_deadman``)."""
    argv = list(sys.argv if args is None else args)
    options, ros_argv = parse(argv)
    interactive = not options.hold
    if interactive and not sys.stdin.isatty():
        print(f'{NODE_NAME}: stdin is not a terminal: give --hold to hold the deadman '
              'without a keyboard', file=sys.stderr)
        sys.exit(2)
    saved = termios.tcgetattr(sys.stdin.fileno()) if interactive else None
    stop = threading.Event()
    built = []

    def make():
        node = DeadmanNode(options)
        built.append(node)
        if interactive:
            tty.setcbreak(sys.stdin.fileno())   # keys one by one, unechoed; Ctrl-C works
            threading.Thread(target=_read_keys, args=(node, stop), daemon=True).start()
        return node

    try:
        status = run(make, NODE_NAME, ros_argv)
    finally:
        stop.set()
        if saved is not None:
            termios.tcsetattr(sys.stdin.fileno(), termios.TCSADRAIN, saved)
    sys.exit(status)
