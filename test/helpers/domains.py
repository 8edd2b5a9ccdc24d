"""
ROS domain ids handed out uniquely across processes, one per test.

As ament_cmake_ros' ``domain_coordinator`` does for ament's isolated tests: an id is held
by an exclusive lock on a file of its own in the temporary directory, so that two test
processes (pytest-xdist workers, two checkouts, ``make stress``) never share one. The lock
is the kernel's (``flock``): it goes with its holder, also when that holder is killed.
Released ids are touched, and the least recently used free id is handed out next, so that a
domain is reused as late as possible: whatever a stopped process left in the DDS graph has
the longest time to be gone by then.
"""

from __future__ import annotations

import errno
import fcntl
import os
from pathlib import Path
import tempfile
import time

#: Ids whose DDS ports do not overlap the ephemeral range on Linux (ROS 2's "0-101"); 0 is
#: everybody's default domain and is never used by the tests.
DOMAINS = range(1, 101)
LOCK_DIR = Path(tempfile.gettempdir()) / 'tracked_kinematics_ros_domains'


class DomainLease:
    """One held domain id; :meth:`release` gives it back."""

    def __init__(self, domain_id: int, fd: int, path: Path) -> None:
        self.domain_id = domain_id
        self._fd = fd
        self._path = path

    def release(self) -> None:
        """Mark the id as just used and unlock it (once)."""
        if self._fd < 0:
            return
        try:
            os.utime(self._fd)
        finally:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = -1

    def __enter__(self) -> DomainLease:
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def _last_used(path: Path) -> float:
    try:
        return path.stat().st_mtime
    except FileNotFoundError:
        return 0.0


def acquire(timeout: float = 120.0, lock_dir: Path = LOCK_DIR,
            domains: range = DOMAINS) -> DomainLease:
    """
    Hold a domain id no other process holds, least recently used first.

    Raises
    ------
    TimeoutError
        When every id stays taken for ``timeout`` seconds.

    """
    lock_dir.mkdir(mode=0o777, exist_ok=True)
    deadline = time.monotonic() + timeout
    while True:
        paths = sorted((lock_dir / f'{domain}.lock' for domain in domains), key=_last_used)
        for path in paths:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as err:
                os.close(fd)
                if err.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
                    continue
                raise
            return DomainLease(int(path.stem), fd, path)
        if time.monotonic() > deadline:
            raise TimeoutError(f'all {len(domains)} ROS domain ids are taken (locks in '
                               f'{lock_dir})')
        time.sleep(0.1)
