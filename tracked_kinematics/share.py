"""Locate the files the package installs to share/ (config/, launch/)."""

from __future__ import annotations

import os
from pathlib import Path
import sys

PACKAGE = 'tracked_kinematics'


def share_dir() -> Path:
    """
    Directory holding ``config/`` and ``launch/`` of this package.

    Looks, in order, in the ament index (a colcon install or a sourced workspace), next to the
    source tree (an editable or in-tree use, where data files are not installed), and under
    ``sys.prefix/share`` (a ``pip install`` into a venv).

    Raises
    ------
    FileNotFoundError
        When none of them has the package's files.

    """
    candidates = []
    try:
        from ament_index_python.packages import get_package_share_directory
        candidates.append(Path(get_package_share_directory(PACKAGE)))
    except Exception:  # noqa: BLE001 -- not installed, not indexed: try the next place
        pass
    candidates.append(Path(__file__).resolve().parent.parent)
    candidates.append(Path(sys.prefix) / 'share' / PACKAGE)
    for candidate in candidates:
        if (candidate / 'config').is_dir():
            return candidate
    raise FileNotFoundError(
        f'cannot find the share directory of {PACKAGE} (looked in '
        f'{", ".join(os.fspath(c) for c in candidates)})')


def config_file(name: str) -> Path:
    """Path of a file shipped in ``config/`` (for example ``auriga_alpha_hard_floor.yaml``)."""
    path = share_dir() / 'config' / name
    if not path.is_file():
        raise FileNotFoundError(f'{PACKAGE} ships no config/{name} (in {path.parent})')
    return path
