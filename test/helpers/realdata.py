"""
The real robot bags of ../shared/realdata (its README.md): where they are, skipped if absent.

CI keeps the shared folder beside the clone, ``<repository>/../shared/realdata``;
``TRACKED_KINEMATICS_REALDATA`` names another folder (a worktree elsewhere).
"""

import os
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[2]

# name: (sprocket radius m, track width m, ground-truth latency s of the README's table)
BAGS = {
    'husky_wetgrass_part1': (0.15875, 0.5384615384615384, 0.11),
    'warthog_grass_2024-07-18_16h59': (0.3, 1.08, 0.26),
    'warthog_grass_2024-07-29_14h04': (0.3, 1.08, 0.24),
    'warthog_grass_2024-08-08_16h11': (0.3, 1.08, 0.19),
}
TOPIC = '/icp/pose'


def folder():
    """Return the folder of the real bags, or None."""
    named = os.environ.get('TRACKED_KINEMATICS_REALDATA')
    path = Path(named) if named else REPOSITORY.parent / 'shared' / 'realdata'
    return path if (path / 'README.md').is_file() else None


def bag(name):
    """Return the path of one real bag; skip the test when the real data are not here."""
    base = folder()
    if base is None or not (base / name).is_dir():
        pytest.skip(f'real data not found ({name}): set TRACKED_KINEMATICS_REALDATA')
    return base / name
