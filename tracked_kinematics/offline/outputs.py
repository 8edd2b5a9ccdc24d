"""
Output files of the offline tools: checked before any work, written atomically, all or none.

Every tool that writes files (YAML, JSON, CSV, PNG, bags) goes through :class:`Outputs`::

    with Outputs(force=args.force) as out:
        out.add('--output', args.output)              # checked now, before any work
        out.add('--report', args.report)
        ...                                           # the work
        out.write_text('--output', yaml_text)         # staged next to the target
        with out.path('--plot') as tmp:               # for writers that want a path
            figure.savefig(tmp)
    # leaving the block renames every staged file onto its target; an exception instead
    # removes them all, so a failed run leaves nothing new behind

The rules (docs/output-files.md):

- a target is a regular file or a new path in an existing, writable directory; a symbolic
  link, a directory (unless the output is a directory, as a bag is), a device, a FIFO or a
  socket is refused with a message naming the flag;
- an existing file is replaced only with ``--force``; an existing directory never is;
- two outputs of one run may not be the same file;
- data are written to a temporary file in the target's directory, flushed and fsynced, and
  renamed onto the target only when the whole run succeeded; without ``--force`` the rename
  never replaces a file that appeared meanwhile.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
import shutil
import stat
import tempfile

from tracked_kinematics.core.errors import TrackedKinematicsError

_KINDS = {stat.S_IFDIR: 'a directory', stat.S_IFCHR: 'a character device',
          stat.S_IFBLK: 'a block device', stat.S_IFIFO: 'a FIFO', stat.S_IFSOCK: 'a socket',
          stat.S_IFLNK: 'a symbolic link'}


class OutputError(TrackedKinematicsError):
    """An output path that cannot or may not be written; the message names the flag."""


def _what(mode: int) -> str:
    return _KINDS.get(stat.S_IFMT(mode), 'not a regular file')


def check_output(flag: str, path, force: bool = False, directory: bool = False) -> Path:
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
        The output is a directory (a rosbag2 bag): it must not exist.

    Raises
    ------
    OutputError
        With the reason, naming ``flag`` and ``path``.

    """
    path = Path(os.fspath(path))
    if not str(path) or path.name in ('', '.', '..'):
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
                              'itself')
        if directory:
            raise OutputError(f'{flag} {path} exists; choose a new path for the bag')
        if not stat.S_ISREG(info.st_mode):
            raise OutputError(f'{flag} {path} is {_what(info.st_mode)}, not a regular file')
        if not force:
            raise OutputError(f'{flag} {path} exists; use --force to replace it')
    parent = path.parent if str(path.parent) else Path('.')
    if not parent.is_dir():
        raise OutputError(f'{flag} {path}: directory {parent} does not exist')
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f'{flag} {path}: directory {parent} is not writable')
    return path


class Outputs:
    """
    The outputs of one run: checked together at the start, committed together at the end.

    Parameters
    ----------
    force : bool
        ``--force``: existing regular files may be replaced.

    """

    def __init__(self, force: bool = False):
        self.force = bool(force)
        self._targets: dict[str, tuple[Path, bool]] = {}
        self._staged: dict[str, Path] = {}

    # --- planning --------------------------------------------------------------------------

    def add(self, flag: str, path, directory: bool = False) -> Path | None:
        """
        Check an output (``None`` = not asked for) and reserve it; return its path.

        Raises
        ------
        OutputError
            When it may not be written, or another output of the run is the same file.

        """
        if path is None:
            return None
        target = check_output(flag, path, self.force, directory)
        key = os.path.realpath(target)
        for other, (other_path, _) in self._targets.items():
            if os.path.realpath(other_path) == key:
                raise OutputError(f'{flag} and {other} name the same file {target}')
        self._targets[flag] = (target, directory)
        return target

    def __contains__(self, flag: str) -> bool:
        """Whether an output of this name was asked for."""
        return flag in self._targets

    def target(self, flag: str) -> Path:
        """Return the final path of an output."""
        return self._targets[flag][0]

    # --- writing ---------------------------------------------------------------------------

    def _stage(self, flag: str) -> Path:
        if flag not in self._targets:
            raise KeyError(f'output {flag} was not added')
        if flag in self._staged:
            raise RuntimeError(f'output {flag} written twice')
        target, directory = self._targets[flag]
        parent = target.parent if str(target.parent) else Path('.')
        prefix = f'.{target.name}.tmp-'
        if directory:
            tmp = Path(tempfile.mkdtemp(prefix=prefix, dir=parent))
            os.rmdir(tmp)  # writers (rosbags) create the directory themselves
        else:
            fd, name = tempfile.mkstemp(prefix=prefix, dir=parent)
            os.close(fd)
            tmp = Path(name)
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)
        self._staged[flag] = tmp
        return tmp

    @contextlib.contextmanager
    def path(self, flag: str):
        """
        Yield a temporary path for ``flag`` for a writer that wants a file name.

        The file (or directory, for a directory output) is renamed onto the target when
        the run commits; an exception inside the block removes it at once.
        """
        tmp = self._stage(flag)
        try:
            yield tmp
        except BaseException:
            _remove(tmp)
            self._staged.pop(flag, None)
            raise
        if not self._targets[flag][1]:
            _fsync_file(tmp)

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

        Raises
        ------
        OutputError
            When a target appeared meanwhile (without ``--force``) or turned into something
            that is not a regular file; staged files not yet renamed are removed.

        """
        written = []
        try:
            for flag, tmp in list(self._staged.items()):
                target, directory = self._targets[flag]
                check_output(flag, target, self.force, directory)
                if directory:
                    os.rename(tmp, target)
                elif self.force:
                    os.replace(tmp, target)
                else:
                    _rename_no_replace(flag, tmp, target)
                del self._staged[flag]
                written.append(target)
                _fsync_dir(target.parent)
        except BaseException:
            self.abort()
            raise
        return written

    def abort(self) -> None:
        """Remove every staged output (the targets are left as they were)."""
        for tmp in self._staged.values():
            _remove(tmp)
        self._staged.clear()

    def __enter__(self) -> Outputs:
        """Start the run."""
        return self

    def __exit__(self, kind, value, traceback) -> None:
        """Commit on success; on any exception remove what was staged."""
        if kind is None:
            self.commit()
        else:
            self.abort()


def _rename_no_replace(flag: str, tmp: Path, target: Path) -> None:
    try:
        os.link(tmp, target)  # fails if target exists: never replaces a file
    except FileExistsError:
        raise OutputError(f'{flag} {target} appeared while the tool ran; use --force to '
                          'replace it') from None
    except OSError:
        # No hard links on this file system: check and rename (a narrow race remains).
        if os.path.lexists(target):
            raise OutputError(f'{flag} {target} exists; use --force to replace it') from None
        os.rename(tmp, target)
        return
    os.unlink(tmp)


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


def _remove(path: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
