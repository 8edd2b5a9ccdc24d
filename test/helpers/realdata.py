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


def from_argv(argv, names):
    """
    Return the real-data folder and the names chosen on a benchmark's command line.

    A directory among ``argv`` is the folder (else :func:`folder`, else ../shared/realdata);
    the arguments among ``names`` are chosen, all of ``names`` when none is.
    """
    given = [a for a in argv if not a.startswith('--')]
    base = Path(given[0]) if given and Path(given[0]).is_dir() else \
        folder() or REPOSITORY.parent / 'shared' / 'realdata'
    return base, [a for a in given if a in names] or list(names)


def bag(name):
    """Return the path of one real bag; skip the test when the real data are not here."""
    base = folder()
    if base is None or not (base / name).is_dir():
        pytest.skip(f'real data not found ({name}): set TRACKED_KINEMATICS_REALDATA')
    return base / name


def split_bag(path: Path, out: Path, share: float) -> tuple[Path, Path]:
    """
    Copy a bag into its first ``share`` of time and the rest, two bags under ``out``.

    ``<name>_train`` and ``<name>_test``: a single-run set fitted on its start and scored on
    the rest, which starts mid-drive (a node restarted while the robot drives).
    """
    from rosbags.rosbag2 import Reader, Writer
    parts = (out / f'{path.name}_train', out / f'{path.name}_test')
    with Reader(path) as reader:
        cut = reader.start_time + int(share * (reader.end_time - reader.start_time))
        writers = [Writer(p, version=8) for p in parts]
        for w in writers:
            w.open()
        conns = [{c.id: w.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data,
                                         rihs01=c.digest,
                                         offered_qos_profiles=c.ext.offered_qos_profiles)
                  for c in reader.connections} for w in writers]
        for conn, stamp, data in reader.messages():
            k = 0 if stamp < cut else 1
            writers[k].write(conns[k][conn.id], stamp, data)
        for w in writers:
            w.close()
    return parts
