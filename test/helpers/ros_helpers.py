"""Helpers for tests on a real rclpy graph: wait on conditions, run console scripts."""

import os
from pathlib import Path
import signal
import subprocess
import sys
import time

BIN = Path(sys.executable).parent


def spin_until(executor, condition, timeout=5.0):
    """Spin ``executor`` until ``condition()`` is true or ``timeout`` s pass; return it."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        executor.spin_once(timeout_sec=0.02)
    return bool(condition())


class ConsoleScript:
    """
    A console script of the package run as a subprocess (``with`` stops it by SIGINT).

    Output goes to files so that a chatty process never blocks on a full pipe.
    """

    def __init__(self, name, *args, tmp_path, env=None):
        self.name = name
        self.stdout_path = tmp_path / f'{name}.stdout'
        self.stderr_path = tmp_path / f'{name}.stderr'
        self._stdout = open(self.stdout_path, 'w')
        self._stderr = open(self.stderr_path, 'w')
        self.process = subprocess.Popen(
            [str(BIN / name), *map(str, args)], stdout=self._stdout, stderr=self._stderr,
            env={**os.environ, 'PYTHONUNBUFFERED': '1', **(env or {})})

    def __enter__(self):
        return self

    def stop(self, timeout=10.0):
        """SIGINT, then SIGKILL after ``timeout``; return the exit status."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._stdout.close()
        self._stderr.close()
        return self.process.returncode

    def __exit__(self, *exc):
        self.stop()

    def wait(self, timeout=30.0):
        """Wait for a process that exits by itself; return its status."""
        code = self.process.wait(timeout)
        self._stdout.close()
        self._stderr.close()
        return code

    @property
    def output(self):
        """Return what the process wrote so far, stdout then stderr."""
        return self.stdout_path.read_text() + self.stderr_path.read_text()
