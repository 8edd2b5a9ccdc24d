"""
Opening a bag, checking the topics asked for, and a progress bar while it is read.

rosbag2 directories (sqlite3, mcap) and ROS 1 ``.bag`` files are opened with
``rosbags.highlevel.AnyReader``; :func:`guarded` turns any failure of the reader into one
:class:`~tracked_kinematics.offline.errors.BagError` line.
"""

from __future__ import annotations

from pathlib import Path

from rosbags.highlevel import AnyReader
from tracked_kinematics.core.errors import SensorDataError
from tracked_kinematics.offline.errors import BagError


class Progress:
    """A progress bar on stderr when it is a terminal (tqdm), else nothing."""

    def __init__(self, total: int, description: str, enabled: bool):
        self._bar = None
        self._pending = 0
        if enabled:
            try:
                from tqdm import tqdm
            except ImportError:  # optional: progress is a nicety
                return
            self._bar = tqdm(total=total, desc=description, unit='msg', unit_scale=True,
                             leave=False)

    def step(self) -> None:
        if self._bar is not None:
            self._pending += 1
            if self._pending == 2000:
                self._bar.update(self._pending)
                self._pending = 0

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def _open(path: Path) -> AnyReader:
    if not path.exists():
        raise BagError(f'bag not found: {path}')
    if path.is_dir() and not (path / 'metadata.yaml').exists():
        inside = sorted(p.name for p in path.iterdir())[:3]
        raise BagError(f'{path} is not a bag: a rosbag2 bag is a directory with a '
                       'metadata.yaml (and its .mcap or .db3 files); this one holds '
                       + (', '.join(inside) + (', ...' if len(inside) == 3 else '')
                          if inside else 'nothing'))
    return AnyReader([path])


def topic_list(reader: AnyReader) -> str:
    topics = sorted((c.topic, c.msgtype) for c in reader.connections)
    return ', '.join(f'{t} ({m})' for t, m in dict(topics).items()) or 'none'


def topic_connections(reader: AnyReader, path: Path, topic: str, allowed, what: str):
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns:
        raise BagError(f'{path}: no topic {topic} for the {what}; topics present: '
                       f'{topic_list(reader)}')
    bad = sorted({c.msgtype for c in conns if c.msgtype not in allowed})
    if bad:
        raise BagError(f'{path}: topic {topic} has type {", ".join(bad)}; the {what} must be '
                       f'{" or ".join(allowed)}')
    return conns


def guarded(path: Path, read, *args):
    """Open a bag and ``read(reader, path, *args)`` it; any reader failure is a BagError."""
    try:
        reader = _open(path)
        with reader:
            return read(reader, path, *args)
    except (BagError, SensorDataError):   # already one line about the bag's content
        raise
    except Exception as err:  # noqa: BLE001 -- rosbags and sqlite raise many kinds
        detail = ' '.join(str(err).split()) or type(err).__name__
        raise BagError(f'cannot read bag {path}: {detail} (truncated or corrupt?)') from None
