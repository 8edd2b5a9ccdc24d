"""
Stopping a node's console script at a random instant, with its input flowing.

Shared by the suite (a few stops per node) and ``make stress`` (``tools/stress.py``: many,
beside CPU-bound processes). A stop is a SIGINT or SIGTERM, sometimes a second one shortly
after, sent at a random moment of the node's life: as soon as the process exists, while it
imports, while it builds itself, or while it takes a 1 kHz input. The outcome records the
exit status, whether the node was up (its first log line) when signalled, whether the
package had taken the signals yet (read from /proc just before the signal), a traceback in
its output, and a hang (no exit in ``hang_timeout`` s).

A signal before the package's first line lands in the interpreter's own start-up, which no
code of the package can reach (docs/testing.md): it takes Python's course, which
:attr:`Stop.python_course` recognises. From the package's first line on, every stop must
be an exit 0 without a traceback.
"""

from __future__ import annotations

from dataclasses import dataclass
import os
from pathlib import Path
import random
import re
import signal
import subprocess
import sys
import threading
import time

BIN = Path(sys.executable).parent
PACKAGE = Path(__file__).resolve().parents[2] / 'tracked_kinematics'
EARLY = 1.5
"""Seconds: ``when='early'`` signals at a random instant this soon after the process starts."""
LOST_AFTER = 10.0
"""Seconds: a node signalled before the package ran that still runs this long after lost it."""
VEHICLE_ARGS = ('-p', 'track_width:=0.42', '-p', 'sprocket_radius:=0.1')

#: Per node: extra arguments and the words of its first log line once it is up.
NODES = {
    'odometry_node': (('-p', 'publish_tf:=false'), 'ICR model'),
    'cmd_vel_translator': (('-p', 'rate:=1000.0'), 'ICR model'),
    'icr_estimator': ((), 'estimating'),
    'tracked_simulator': (('-p', 'real_time_factor:=10.0'), 'simulating'),
    # Its fit would go to {workdir}/fit.yaml; with no deadman held it never moves or fits.
    'calibration_drive': (('-p', 'output:={workdir}/fit.yaml'), 'calibration drive:'),
}


def package_frames(output: str) -> list[str]:
    """Return the files of the package named in a traceback of ``output``."""
    return [path for path in re.findall(r'File "([^"]+)"', output)
            if Path(path).resolve().is_relative_to(PACKAGE)]


def python_course(signum: int, status: int | None, output: str) -> bool:
    """
    Return whether ``signum`` ended a process before the package ran, as Python ends any.

    Death by the signal with no output, or (SIGINT, once the interpreter has its own
    handler) a KeyboardInterrupt traceback with no frame of the package, exit status 1 in
    the site import or death by SIGINT after it.
    """
    if status == -signum and not output.strip():
        return True
    return (signum == signal.SIGINT and status in (1, -signal.SIGINT)
            and output.rstrip().endswith('KeyboardInterrupt') and not package_frames(output))


@dataclass
class Stop:
    """What one stop did."""

    node: str
    signals: tuple[str, ...]
    delay: float
    up: bool
    status: int | None  # None: it hung (was killed)
    traceback: bool
    output: str
    before_package: bool = False
    """The first signal was sent before the process caught SIGTERM: the package had not run."""
    lost: bool = False
    """... and the node still ran :data:`LOST_AFTER` s later: Python lost it (one more sent)."""

    @property
    def python_course(self) -> bool:
        """Return whether the first signal ended the process before the package ran."""
        return self.before_package and python_course(
            signal.Signals[self.signals[0]], self.status, self.output)

    @property
    def clean(self) -> bool:
        """Return whether the stop was clean: exit 0 and no traceback, or Python's course."""
        return (self.status == 0 and not self.traceback) or self.python_course


class Feeder:
    """Publish joint_states and cmd_vel at about 1 kHz from a thread, on a context of its own."""

    def __init__(self, domain_id: int, rate: float = 1000.0) -> None:
        import rclpy
        from rclpy.node import Node
        from geometry_msgs.msg import Twist
        from sensor_msgs.msg import JointState
        self._context = rclpy.Context()
        rclpy.init(context=self._context, domain_id=domain_id,
                   signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
        self._node = Node('stress_feeder', context=self._context)
        self._joints = self._node.create_publisher(JointState, 'joint_states', 10)
        self._cmd = self._node.create_publisher(Twist, 'cmd_vel', 10)
        self._msg = JointState(name=['left_sprocket_joint', 'right_sprocket_joint'])
        self._twist = Twist()
        self._period = 1.0 / rate
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        i = 0
        t0 = time.time()
        while not self._stop.wait(self._period):
            i += 1
            t = t0 + i * self._period
            sec = int(t)
            self._msg.header.stamp.sec, self._msg.header.stamp.nanosec = sec, int((t - sec) * 1e9)
            self._msg.position = [1e-3 * i, 1.2e-3 * i]
            self._joints.publish(self._msg)
            self._twist.linear.x, self._twist.angular.z = 0.3, 0.2 * ((i // 500) % 2)
            self._cmd.publish(self._twist)

    def close(self) -> None:
        """Stop publishing, destroy the node, then shut the context down."""
        self._stop.set()
        self._thread.join(5.0)
        self._node.destroy_node()
        self._context.try_shutdown()


def catches_sigterm(pid: int) -> bool:
    """Return whether process ``pid`` has a handler for SIGTERM (from /proc)."""
    try:
        with open(f'/proc/{pid}/status') as status:
            for line in status:
                if line.startswith('SigCgt:'):
                    return bool(int(line.split()[1], 16) >> (signal.SIGTERM - 1) & 1)
    except OSError:
        pass
    return False


def stop_once(name: str, rng: random.Random, workdir: Path, env: dict[str, str] | None = None,
              startup: float = 3.0, hang_timeout: float = 60.0, when: str | None = None,
              signals: tuple[int, ...] | None = None) -> Stop:
    """
    Start ``name``, signal it at a random instant, wait for it to exit.

    ``when`` is ``'at once'`` (as soon as the process exists, in the interpreter's own
    start-up), ``'early'`` (a random instant of the first :data:`EARLY` s after the process
    started, waiting for nothing: before or after the package's first line),
    ``'startup'`` (a random instant of the first ``startup`` s after the package
    has begun to catch SIGTERM, which should cover the node's own start-up on this machine:
    imports, parameters), ``'running'`` (a
    random instant of the first 0.5 s after its first log line, input flowing) or None,
    any of the last three at random: every phase is hit whatever the machine's speed.
    ``signals`` are sent in order with random gaps of up to 0.2 s; by default one or (three
    times in ten) two of SIGINT and SIGTERM at random. A node signalled before the package
    ran that still runs :data:`LOST_AFTER` s later gets one more SIGTERM (:attr:`Stop.lost`).
    """
    extra, up_words = NODES[name]
    workdir.mkdir(parents=True, exist_ok=True)
    extra = [arg.format(workdir=workdir) for arg in extra]
    out_path = workdir / f'{name}.log'
    with open(out_path, 'w') as out:
        process = subprocess.Popen(
            [str(BIN / name), '--ros-args', *VEHICLE_ARGS, *extra], stdout=out,
            stderr=subprocess.STDOUT,
            env={**os.environ, 'PYTHONUNBUFFERED': '1', **(env or {})})
        started = time.monotonic()
        when = when or rng.choice(['early', 'startup', 'running'])
        if when == 'at once':
            pass
        elif when == 'early':
            time.sleep(rng.uniform(0.0, EARLY))
        elif when == 'startup':
            # From the moment the package catches SIGTERM (its first lines): before, the
            # interpreter itself is starting, and a signal there takes Python's own course
            # (death, or a KeyboardInterrupt in its site import) before any code of ours.
            deadline = started + hang_timeout
            while (not catches_sigterm(process.pid) and process.poll() is None
                   and time.monotonic() < deadline):
                time.sleep(0.002)
            time.sleep(rng.uniform(0.0, startup))
        else:  # once up, at a random moment of the input
            deadline = started + hang_timeout
            while (up_words not in out_path.read_text(errors='replace')
                   and process.poll() is None and time.monotonic() < deadline):
                time.sleep(0.01)
            time.sleep(rng.uniform(0.0, 0.5))
        delay = time.monotonic() - started
        up = up_words in out_path.read_text(errors='replace')
        if signals is None:
            sigs = [rng.choice([signal.SIGINT, signal.SIGTERM])]
            if rng.random() < 0.3:
                sigs.append(rng.choice([signal.SIGINT, signal.SIGTERM]))
        else:
            sigs = list(signals)
        before_package = not catches_sigterm(process.pid)
        for k, sig in enumerate(sigs):
            if process.poll() is None:
                process.send_signal(sig)
            if k + 1 < len(sigs):
                time.sleep(rng.uniform(0.0, 0.2))
        lost = False
        if before_package:
            try:
                process.wait(LOST_AFTER)
            except subprocess.TimeoutExpired:
                lost = True
                process.send_signal(signal.SIGTERM)
        try:
            status = process.wait(hang_timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
            status = None
    output = out_path.read_text(errors='replace')
    return Stop(name, tuple(s.name for s in sigs), delay, up, status,
                'Traceback' in output, output, before_package, lost)


def summary(stops: list[Stop]) -> str:
    """Return the counts a person reads: per node, clean / traceback / hang / exit codes."""
    lines = []
    for name in sorted({s.node for s in stops}):
        mine = [s for s in stops if s.node == name]
        up = [s for s in mine if s.up]
        codes = sorted({s.status for s in mine if s.status not in (0, None)})
        lines.append(
            f'{name:20s} stops {len(mine):3d} (up {len(up):3d}, twice '
            f'{sum(len(s.signals) > 1 for s in mine):3d}): clean {sum(s.clean for s in mine):3d}'
            f', tracebacks {sum(s.traceback for s in mine):2d}'
            f', hangs {sum(s.status is None for s in mine):2d}'
            f', non-zero exits {sum(s.status not in (0, None) for s in mine):2d}'
            + (f' {codes}' if codes else '')
            + f' (once up: {sum(s.status not in (0, None) for s in up)}; signalled before '
            f'the package ran: {sum(s.before_package for s in mine)}, of which ended by '
            f'Python {sum(s.python_course for s in mine)}, lost by Python '
            f'{sum(s.lost for s in mine)})')
    return '\n'.join(lines)
