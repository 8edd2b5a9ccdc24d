"""
The demo's output directory and its manifest of what the demo created there.

The manifest (``.tracked_kinematics_demo``, JSON) lists exactly the files, bags and
directories a run of ``tracked_kinematics_demo`` created in its ``--output``. A rerun removes
what the manifest lists and nothing else (never following a symbolic link); any other file
in the way is replaced only with ``--force`` (a bag or a directory never). A failed or
interrupted run removes what it wrote. docs/tools/tracked_kinematics_demo.md describes the
directory.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
import json
import os
from pathlib import Path, PurePosixPath
import stat

from tracked_kinematics.offline import signals
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.outputs import (
    check_output, finished, OutputError, Outputs, unfinished)

PROG = 'tracked_kinematics_demo'
MANIFEST = '.tracked_kinematics_demo'
"""The manifest in the output directory: what the demo created there (JSON)."""
MARKER = MANIFEST
"""Former name of the manifest (older demos wrote a one-line marker under this name)."""


class DemoError(UsageError):
    """A bad argument or an output that cannot be written (exit status 2, one line)."""


@dataclass
class Entry:
    """
    One thing the demo created in its output directory.

    Attributes
    ----------
    kind : {'file', 'bag', 'dir'}
        A regular file, a rosbag2 directory (with the names of its files), a directory.
    path : str
        Relative to the output directory, ``/``-separated.
    files : list of str
        A bag's files (metadata.yaml and its storage files); empty otherwise.
    stamp : list of int
        A file's size and modification time (ns) once written: a file changed since is
        the user's, not the demo's.
    before : list of int
        The stamp of a file that was in the way when the entry was recorded (replaced with
        ``--force``): until it changes, it is not the demo's.
    listed : bool
        A bag's files were listed once it was written (not stored).

    """

    kind: str
    path: str
    files: list = field(default_factory=list)
    stamp: list = field(default_factory=list)
    before: list = field(default_factory=list)
    listed: bool = field(default=False, compare=False)

    def to_json(self) -> dict:
        """Return the entry as the manifest stores it."""
        entry = {'kind': self.kind, 'path': self.path}
        if self.kind == 'bag':
            entry['files'] = list(self.files)
        if self.stamp:
            entry['stamp'] = list(self.stamp)
        if self.before:
            entry['before'] = list(self.before)
        return entry

    def matches(self, info) -> bool:
        """Whether the file ``info`` describes is the demo's: as it wrote it, or new."""
        now = _stamp(info)
        if self.stamp:
            return self.stamp == now
        return not self.before or self.before != now


def bag_files(path: str, storage: str) -> list[str]:
    """
    Return the files of the bag ``path`` the demo writes (with ``storage``), before it does.

    Recorded with the bag's entry before it is written, so that a run interrupted once the
    bag is in place but before :meth:`DemoDirectory.written` has listed it still removes it.
    """
    name = PurePosixPath(path).name
    return ['metadata.yaml', f'{name}.{"db3" if storage == "sqlite3" else storage}']


def _stamp(info) -> list:
    return [info.st_size, info.st_mtime_ns]


def planned_outputs(vehicle: str, terrain: str, heldout: list[str]) -> list[Entry]:
    """Return what a run will create, relative to its output directory, parents first."""
    calibration = f'calibration/{vehicle}_{terrain}'
    entries = [Entry('dir', 'calibration'), Entry('bag', calibration),
               Entry('file', f'{calibration}.truth.yaml'),
               Entry('file', f'{terrain}.yaml'), Entry('file', 'identify_report.json'),
               Entry('file', 'identify.png'), Entry('dir', 'heldout')]
    for name in heldout:
        entries += [Entry('bag', f'heldout/{name}'),
                    Entry('file', f'heldout/{name}.truth.yaml')]
    return entries + [Entry('file', 'heldout.csv'), Entry('file', 'heldout.png'),
                      Entry('file', 'consistency.png')]


def _lstat(path: Path):
    try:
        return os.lstat(path)
    except FileNotFoundError:
        return None


def _plain(rel: str) -> bool:
    """Whether a manifest path is a plain relative path (no '..', not absolute)."""
    parts = PurePosixPath(rel).parts
    return bool(parts) and not PurePosixPath(rel).is_absolute() and all(
        part not in ('', '.', '..') and '\\' not in part for part in parts)


def _real_parents(directory: Path, rel: str) -> bool:
    """Whether no directory between ``directory`` and ``rel`` is a link or a file (or absent)."""
    path = directory
    for part in PurePosixPath(rel).parts[:-1]:
        path = path / part
        info = _lstat(path)
        if info is None:
            return True
        if not stat.S_ISDIR(info.st_mode):
            return False
    return True


class DemoDirectory:
    """
    The demo's output directory and its manifest.

    :meth:`prepare` checks, before any work, that the run may write every output; removes
    what the previous run's manifest lists (and nothing else); creates the directories.
    :meth:`record` adds an output to the manifest before it is written, so that a killed run
    leaves a manifest a rerun can clean; :meth:`fail` removes what this run created.

    Parameters
    ----------
    directory : path-like
        ``--output``.
    force : bool
        ``--force``: files in the way that the demo did not write may be replaced.

    """

    def __init__(self, directory, force: bool = False):
        self.directory = Path(directory)
        self.force = force
        self.entries: list[Entry] = []
        self.created: list[Path] = []   # the output directory and parents made by this run
        self.changed = False            # prepare() has begun to change the directory
        self.cleared = False            # ... and removed what the previous run wrote

    @property
    def manifest(self) -> Path:
        """Path of the manifest."""
        return self.directory / MANIFEST

    def _error(self, message: str) -> DemoError:
        return DemoError(f'--output {self.directory}: {message}')

    def read_manifest(self) -> list[Entry]:
        """
        Return the entries of the previous run (none for a new or empty directory).

        Raises
        ------
        DemoError
            When the directory is a link or not a directory, or holds files but no manifest
            of the demo.

        """
        info = _lstat(self.directory)
        if info is None:
            return []
        if stat.S_ISLNK(info.st_mode):
            raise self._error('is a symbolic link; the demo does not follow it, give the '
                              'directory itself')
        if not stat.S_ISDIR(info.st_mode):
            raise self._error('exists and is not a directory')
        manifest = _lstat(self.manifest)
        if manifest is None:
            if any(self.directory.iterdir()):
                raise self._error('is not empty and was not written by the demo; choose '
                                  'another directory')
            return []
        if not stat.S_ISREG(manifest.st_mode):
            raise self._error(f'{MANIFEST} is not a regular file; the directory was not '
                              'written by the demo')
        try:
            text = self.manifest.read_text(encoding='utf-8')
        except (OSError, UnicodeDecodeError) as err:
            raise self._error(f'cannot read {MANIFEST}: {err}') from None
        if text.startswith(f'written by {PROG}'):
            raise self._error('was written by an older demo that kept no list of its files; '
                              'remove the directory or choose another --output')
        try:
            doc = json.loads(text)
            entries = [Entry(e['kind'], e['path'], [str(f) for f in e.get('files', ())],
                             [int(v) for v in e.get('stamp', ())],
                             [int(v) for v in e.get('before', ())]) for e in doc['entries']]
            return [e for e in entries if e.kind in ('file', 'bag', 'dir') and _plain(e.path)
                    and all(_plain(f) and '/' not in f for f in e.files)]
        except (ValueError, KeyError, TypeError, AttributeError):
            raise self._error(f'{MANIFEST} is not a manifest of the demo; choose another '
                              'directory') from None

    def _check(self, planned: list[Entry], old: list[Entry]) -> None:
        """Refuse, before any work, an output in the way that the demo may not replace."""
        ours = {(e.kind, e.path): e for e in old}
        for entry in planned:
            path = self.directory / entry.path
            if not _real_parents(self.directory, entry.path):
                raise self._error(f'{entry.path.rsplit("/", 1)[0]} is not a directory (a '
                                  'symbolic link is not followed)')
            info = _lstat(path)
            if info is None:
                continue
            mine = ours.get((entry.kind, entry.path))
            if stat.S_ISLNK(info.st_mode):
                raise self._error(f'{entry.path} is a symbolic link; the demo neither follows '
                                  'nor replaces it')
            if entry.kind == 'dir':
                if not stat.S_ISDIR(info.st_mode):
                    raise self._error(f'{entry.path} exists and is not a directory')
            elif entry.kind == 'bag':
                if mine is None:
                    raise self._error(f'{entry.path} exists and was not written by the demo; '
                                      'remove it or choose another --output')
                extra = sorted(set(os.listdir(path)) - set(mine.files)) \
                    if stat.S_ISDIR(info.st_mode) else ['(not a directory)']
                if extra:
                    raise self._error(f'{entry.path} holds files the demo did not write '
                                      f'({", ".join(extra)}); remove them or choose another '
                                      '--output')
            elif mine is not None and stat.S_ISREG(info.st_mode) and not mine.matches(info):
                if not self.force:
                    raise self._error(f'{entry.path} was changed since the demo wrote it; use '
                                      '--force to replace it')
            elif mine is None or not stat.S_ISREG(info.st_mode):
                try:
                    check_output('--output', path, force=self.force)
                except OutputError as err:
                    raise DemoError(str(err)) from None

    def _remove(self, entries: list[Entry]) -> None:
        """Remove what ``entries`` list, files before directories; never follow a link."""
        for entry in sorted(entries, key=lambda e: (e.kind == 'dir', -e.path.count('/'))):
            if not _real_parents(self.directory, entry.path):
                continue
            path = self.directory / entry.path
            info = _lstat(path)
            if info is None:
                continue
            if entry.kind == 'file' and stat.S_ISREG(info.st_mode):
                if entry.matches(info):
                    path.unlink()   # else: the user's file now, left alone
            elif entry.kind in ('bag', 'dir') and stat.S_ISDIR(info.st_mode):
                for name in entry.files:
                    inner = _lstat(path / name)
                    if inner is not None and stat.S_ISREG(inner.st_mode):
                        (path / name).unlink()
                with contextlib.suppress(OSError):   # not empty: someone else's files
                    path.rmdir()

    def save(self) -> None:
        """Write the manifest atomically (every entry of this run so far)."""
        with Outputs(force=True) as out:
            out.add(MANIFEST, self.manifest)
            out.write_text(MANIFEST, json.dumps({
                'tool': PROG, 'note': 'what the demo created in this directory; a rerun '
                'removes exactly these', 'entries': [e.to_json() for e in self.entries]},
                indent=1) + '\n')

    def prepare(self, planned: list[Entry]) -> None:
        """
        Make the directory ready for ``planned``: check, clear the previous run, create.

        Raises
        ------
        DemoError
            When an output may not be written (nothing was changed then).

        """
        old = self.read_manifest()
        self._check(planned, old)
        if self.directory.exists() and not os.access(self.directory, os.W_OK | os.X_OK):
            raise self._error('is not writable')
        # From here on the directory changes: held, so that a signal cannot cut a step in
        # half, and registered, so that an interrupted run undoes it (fail()).
        with signals.held():
            self.changed = True
            unfinished(self)
            if not self.directory.exists():
                try:
                    missing = [p for p in (self.directory, *self.directory.parents)
                               if not os.path.lexists(p)]
                    for parent in reversed(missing):
                        parent.mkdir()
                        self.created.append(parent)
                except OSError as err:
                    self.fail()
                    raise self._error(f'cannot create it: {err.strerror or err}') from None
                if not os.access(self.directory, os.W_OK | os.X_OK):
                    self.fail()
                    raise self._error('is not writable')
            self._remove(old)
            self.cleared = True
            self.entries = []
            for entry in planned:
                if entry.kind == 'dir' and _lstat(self.directory / entry.path) is None:
                    self.record(entry)
                    (self.directory / entry.path).mkdir()
            self.save()

    def record(self, entry: Entry) -> None:
        """Add an output to the manifest, before it is written."""
        info = _lstat(self.directory / entry.path)
        if entry.kind == 'file' and info is not None and stat.S_ISREG(info.st_mode):
            entry.before = _stamp(info)   # a file in the way, replaced with --force
        self.entries.append(entry)
        self.save()

    def written(self) -> None:
        """Record the files of the bags and the stamps of the files written so far."""
        for entry in self.entries:
            path = self.directory / entry.path
            info = _lstat(path)
            if info is None:
                continue
            if entry.kind == 'bag' and not entry.listed and stat.S_ISDIR(info.st_mode):
                entry.files = sorted(os.listdir(path))
                entry.listed = True
            elif entry.kind == 'file' and not entry.stamp and stat.S_ISREG(info.st_mode) \
                    and entry.matches(info):
                entry.stamp = _stamp(info)
        self.save()

    def fail(self) -> None:
        """Remove what this run created (and the directory, if this run created it)."""
        if not self.changed:
            return   # refused before any change: the directory is as it was
        with signals.held():
            self._remove(self.entries)
            self.entries = []
            if self.created:
                with contextlib.suppress(OSError):
                    self.manifest.unlink()
                for path in reversed(self.created):
                    with contextlib.suppress(OSError):
                        path.rmdir()
                self.created = []
            elif self.cleared and self.manifest.exists():
                # The previous run's outputs are gone: the manifest lists this run's, none.
                # (Had removing them failed, it would still list them, for a rerun.)
                with contextlib.suppress(OSError):
                    self.save()
            finished(self)

    def abort(self) -> None:
        """Undo an interrupted run (:func:`~tracked_kinematics.offline.outputs.unfinished`)."""
        self.fail()

    def done(self) -> None:
        """Keep the outputs: the run has succeeded."""
        finished(self)
