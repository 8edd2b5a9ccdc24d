"""
Output files of the offline tools: checked before any work, written atomically, all or none.

The rules (targets, ``--force``, staging, signals, SIGKILL): docs/output-files.md.
"""

from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path
import shutil
import stat
import tempfile

from tracked_kinematics.core.errors import TrackedKinematicsError
from tracked_kinematics.offline import signals

_KINDS = {stat.S_IFDIR: 'a directory', stat.S_IFCHR: 'a character device',
          stat.S_IFBLK: 'a block device', stat.S_IFIFO: 'a FIFO', stat.S_IFSOCK: 'a socket',
          stat.S_IFLNK: 'a symbolic link'}
TEMP_MARK = '.tmp-'
"""Part of the name of every temporary output (``.NAME.tmp-XXXXXXXX``)."""
PROBE_MARK = TEMP_MARK + 'check-'
"""Part of the name of the file the start check creates and removes again."""
PROBE_BYTES = 4096
"""What the start check writes (and fsyncs): one block, so that a full disk is refused."""


class OutputError(TrackedKinematicsError):
    """An output path that cannot or may not be written; the message names the flag."""


_UNFINISHED: dict[int, tuple[int, object]] = {}
"""Work that a failed run must undo (objects with ``abort()``): id -> (order begun, work)."""
_BEGUN = [0]


def unfinished(work) -> None:
    """Register ``work`` (with ``abort()``) as begun: undone if the run fails."""
    if id(work) not in _UNFINISHED:
        _BEGUN[0] += 1
        _UNFINISHED[id(work)] = (_BEGUN[0], work)


def finished(work) -> None:
    """Unregister ``work``: committed or undone."""
    _UNFINISHED.pop(id(work), None)


def begun() -> int:
    """Return a mark for :func:`abort_unfinished`: the work begun so far."""
    return _BEGUN[0]


def abort_unfinished(since: int = 0) -> None:
    """
    Undo, newest first, the work begun after the mark ``since`` and not finished.

    The safety net for a signal no ``except`` sees; ``run_main`` calls it when a run has ended.
    """
    with signals.held():
        for order, work in sorted(_UNFINISHED.values(), key=lambda item: -item[0]):
            if order > since:
                with contextlib.suppress(OSError):
                    work.abort()
                finished(work)


def _what(mode: int) -> str:
    return _KINDS.get(stat.S_IFMT(mode), 'not a regular file')


def check_output(flag: str, path, force: bool = False, directory: bool = False,
                 probe: bool = True) -> Path:
    """
    Check one output path before any work; return it as a :class:`~pathlib.Path`.

    Parameters
    ----------
    flag : str
        The option that names it, for messages (``--output``).
    path : path-like
        The target.
    force : bool
        Whether an existing regular file may be replaced.
    directory : bool
        The output is a bag its writer creates: the path must not exist.
    probe : bool
        Whether to try writing a file in the directory (the commit's re-check does not).

    Raises
    ------
    OutputError
        With the reason, naming ``flag`` and ``path``.

    """
    if not os.fspath(path):
        raise OutputError(f'{flag}: an empty path is not a file name')
    path = Path(os.fspath(path))
    if path.name in ('', '.', '..'):
        raise OutputError(f'{flag} {str(path)!r} is not a file name')
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        info = None
    except OSError as err:
        raise OutputError(f'{flag} {path}: {err.strerror}') from None
    if info is not None:
        if stat.S_ISLNK(info.st_mode):
            raise OutputError(f'{flag} {path} is a symbolic link; give the path of the file '
                              'itself (a link is neither followed nor replaced)')
        if directory:
            raise OutputError(f'{flag} {path} exists; choose a new path for the bag')
        if not stat.S_ISREG(info.st_mode):
            raise OutputError(f'{flag} {path} is {_what(info.st_mode)}, not a regular file')
        if not force:
            raise OutputError(f'{flag} {path} exists; use --force to replace it')
    parent = path.parent if str(path.parent) else Path('.')
    if not parent.is_dir():
        raise OutputError(f'{flag} {path}: directory {parent} does not exist')
    try:
        longest = os.pathconf(parent, 'PC_NAME_MAX')
    except (OSError, ValueError):
        longest = 255
    temporary = len(os.fsencode(f'.{path.name}{PROBE_MARK}XXXXXXXX{path.suffix}'))
    if temporary > longest:
        raise OutputError(f'{flag} {path}: the file name is too long for its temporary file '
                          f'(at most {longest - temporary + len(os.fsencode(path.name))} '
                          'bytes here)')
    if probe:
        _probe(flag, path, parent)
    return path


def _probe(flag: str, path: Path, parent: Path) -> None:
    """Create, write, fsync and remove a temporary file beside ``path``; refuse on failure."""
    try:
        with signals.held():  # the file is removed whatever signal comes
            fd, name = tempfile.mkstemp(prefix=f'.{path.name}{PROBE_MARK}',
                                        suffix=path.suffix, dir=parent)
            try:
                os.write(fd, bytes(PROBE_BYTES))
                os.fsync(fd)
            finally:
                try:
                    os.close(fd)  # a write error may surface only here (NFS)
                finally:
                    os.unlink(name)
    except OSError as err:
        full = err.errno in (errno.ENOSPC, errno.EDQUOT)
        raise OutputError(f'{flag} {path}: directory {parent} '
                          f'{"is full" if full else "is not writable"} (creating a file '
                          f'there: {err.strerror})') from None


def same_file(a, b) -> bool:
    """Whether two paths name the same file (through links of their directories, hard links)."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:   # one of them does not exist (yet)
        return False


class Outputs:
    """
    The outputs of one run: checked together at the start, committed together at the end.

    ``force`` is ``--force``: existing regular files may be replaced. Use::

        with Outputs(force=args.force) as out:
            out.add('--output', args.output)           # checked now, before any work
            out.write_text('--output', yaml_text)      # staged next to the target
            with out.path('--plot') as tmp:            # for writers that want a path
                figure.savefig(tmp)
        # leaving the block renames all onto their targets; an exception removes them all
    """

    def __init__(self, force: bool = False):
        self.force = bool(force)
        self._targets: dict[str, tuple[Path, bool]] = {}
        self._staged: dict[str, Path] = {}

    # --- planning --------------------------------------------------------------------------

    def add(self, flag: str, path, directory: bool = False) -> Path | None:
        """
        Check an output (``None`` = not asked for) and reserve it under ``flag``; return its path.

        ``directory``: a bag its writer creates (the path must not exist). Raises OutputError when
        it may not be written or another output of the run is the same file.
        """
        if path is None:
            return None
        if flag in self._targets:
            raise KeyError(f'output {flag} added twice')
        target = check_output(flag, path, self.force, directory)
        for other, (other_path, _) in self._targets.items():
            if same_file(other_path, target):
                raise OutputError(f'{flag} and {other} name the same file {target}')
        self._targets[flag] = (target, directory)
        return target

    def refuse_inputs(self, label: str, paths, allow=()) -> None:
        """
        Refuse an output that is (or lies inside) one of the run's inputs (``paths``, ``label``).

        ``allow`` names the outputs that may replace an input (``--output`` its ``--params`` file).
        """
        for path in paths:
            if path is None:
                continue
            inside = os.path.isdir(path) and not os.path.islink(path)
            root = os.path.join(os.path.realpath(path), '')
            for flag, (target, _) in self._targets.items():
                if flag not in allow and same_file(target, path):
                    raise OutputError(f'{flag} {target} is also the input {label}; choose '
                                      'another output path')
                if inside and os.path.realpath(target).startswith(root):
                    raise OutputError(f'{flag} {target} is inside the input {label} {path}; '
                                      'choose another output path')

    def __contains__(self, flag: str) -> bool:
        """Whether an output of this name was asked for."""
        return flag in self._targets

    def target(self, flag: str) -> Path:
        """Return the final path of an output."""
        return self._targets[flag][0]

    @property
    def targets(self) -> list[Path]:
        """Every output path, in the order added."""
        return [target for target, _ in self._targets.values()]

    # --- writing ---------------------------------------------------------------------------

    def _stage(self, flag: str) -> Path:
        if flag not in self._targets:
            raise KeyError(f'output {flag} was not added')
        if flag in self._staged:
            raise RuntimeError(f'output {flag} written twice')
        target, directory = self._targets[flag]
        parent = target.parent if str(target.parent) else Path('.')
        prefix = f'.{target.name}{TEMP_MARK}'
        # Held: a signal between creating the temporary file and recording it here would
        # leave a file that nothing removes.
        with signals.held():
            if directory:
                # A hidden directory holding the bag under its own name, so that the bag's
                # files (NAME.db3, NAME.mcap) and metadata.yaml are those the final path needs.
                tmp = Path(tempfile.mkdtemp(prefix=prefix, dir=parent)) / target.name
                self._staged[flag] = tmp
                unfinished(self)
            else:
                # The target's extension last: writers that pick the format by it
                # (matplotlib).
                fd, name = tempfile.mkstemp(prefix=prefix, suffix=target.suffix, dir=parent)
                tmp = Path(name)
                self._staged[flag] = tmp
                unfinished(self)
                os.close(fd)
                os.chmod(tmp, _mode_for(target))
        return tmp

    @contextlib.contextmanager
    def path(self, flag: str):
        """Yield a temporary path for ``flag`` (a bag's does not exist yet)."""
        tmp = self._stage(flag)
        try:
            yield tmp
            _fsync_tree(tmp)
        except BaseException:
            with signals.held():
                _discard(tmp, self._targets[flag][1])
                self._staged.pop(flag, None)
            raise

    def write_bytes(self, flag: str, data: bytes) -> None:
        """Stage ``data`` for ``flag``: written and fsynced now, renamed at commit."""
        with self.path(flag) as tmp:
            with open(tmp, 'wb') as stream:
                stream.write(data)

    def write_text(self, flag: str, text: str) -> None:
        """Stage UTF-8 ``text`` for ``flag``."""
        self.write_bytes(flag, text.encode('utf-8'))

    # --- ending ----------------------------------------------------------------------------

    def commit(self) -> list[Path]:
        """
        Rename every staged output onto its target; return the targets written.

        Targets are re-checked first; a failed rename puts back the ones renamed before it. Raises
        OutputError when a target appeared meanwhile or is no regular file (staged files removed).
        """
        with signals.held():
            return self._commit()

    def _commit(self) -> list[Path]:
        done: list[tuple[Path, Path | None]] = []
        try:
            for flag in self._staged:
                target, directory = self._targets[flag]
                check_output(flag, target, self.force, directory, probe=False)
            # A signal so far: nothing is renamed, everything staged is removed. From the
            # first rename on, the commit completes and the signal ends the run after it.
            signals.raise_pending()
            for flag, tmp in list(self._staged.items()):
                target, directory = self._targets[flag]
                backup = None
                if directory:
                    _rename_new(flag, tmp, target)
                    _remove(tmp.parent)
                elif self.force and os.path.lexists(target):
                    backup = _backup(target)
                    os.replace(tmp, target)
                else:
                    _rename_no_replace(flag, tmp, target)
                del self._staged[flag]
                done.append((target, backup))
            for target, backup in done:
                _fsync_dir(target.parent)
                if backup is not None:
                    _remove(backup)
        except BaseException:
            for target, backup in reversed(done):
                with contextlib.suppress(OSError):
                    if backup is not None:
                        os.replace(backup, target)
                    else:
                        _remove(target)
            self.abort()
            raise
        finished(self)
        return [target for target, _ in done]

    def abort(self) -> None:
        """Remove every staged output (the targets are left as they were)."""
        with signals.held():
            for flag, tmp in list(self._staged.items()):
                _discard(tmp, self._targets[flag][1])
                del self._staged[flag]
            finished(self)

    def __enter__(self) -> Outputs:
        """Start the run."""
        return self

    def __exit__(self, kind, value, traceback) -> None:
        """Commit on success; on any exception remove what was staged."""
        if kind is None:
            self.commit()
        else:
            self.abort()


def _mode_for(target: Path) -> int:
    """Permission bits of a new output: the replaced file's, else 0666 & ~umask."""
    try:
        info = os.lstat(target)
    except OSError:
        info = None
    if info is not None and stat.S_ISREG(info.st_mode):
        return stat.S_IMODE(info.st_mode)
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def _rename_no_replace(flag: str, tmp: Path, target: Path) -> None:
    try:
        os.link(tmp, target)  # fails if target exists: never replaces a file
    except FileExistsError:
        raise OutputError(f'{flag} {target} appeared while the tool ran; use --force to '
                          'replace it') from None
    except OSError:
        # No hard links on this file system: check and rename (a narrow race remains).
        _rename_new(flag, tmp, target)
        return
    os.unlink(tmp)


def _rename_new(flag: str, tmp: Path, target: Path) -> None:
    """Rename onto a target that must not exist (a narrow race remains for directories)."""
    if os.path.lexists(target):
        raise OutputError(f'{flag} {target} appeared while the tool ran; nothing was '
                          'replaced')
    os.rename(tmp, target)


def _backup(target: Path) -> Path | None:
    """Hard-link the file a forced rename replaces, to put it back if the commit fails."""
    backup = target.with_name(f'.{target.name}{TEMP_MARK}old-{os.getpid()}')
    with contextlib.suppress(FileNotFoundError):
        os.unlink(backup)
    try:
        os.link(target, backup)
    except OSError:
        return None
    return backup


def _fsync_tree(path: Path) -> None:
    """Fsync a written file, or every file of a written bag directory and the directory."""
    if not os.path.lexists(path):
        return
    if path.is_dir() and not path.is_symlink():
        for root, _, files in os.walk(path):
            for name in files:
                _fsync_file(Path(root) / name)
            _fsync_dir(Path(root))
    else:
        _fsync_file(path)


def _fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(path: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(path if str(path) else '.', os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _discard(tmp: Path, directory: bool) -> None:
    """Remove a staged output (a bag: its hidden holder directory too)."""
    _remove(tmp)
    if directory:
        with contextlib.suppress(OSError):
            os.rmdir(tmp.parent)


def _remove(path: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
