"""
Every output flag of every tool, attacked as a careless user would (issue 14 items 9-11).

Each tool is given a path that it must refuse before any work: /dev/null, a FIFO, a symbolic
link (to a file, or dangling), a directory, an existing file without --force, a missing
directory, the same path twice. The refusal is one line naming the flag, exit status 2, and
nothing in the directory changes. The inputs are chosen so that the tool would fail at its
first step of work (a missing bag, an unknown vehicle): the output error coming first shows
that outputs are checked before any work.
"""

import os
import stat
import subprocess
import sys

import pytest
from tracked_kinematics.offline import bag_simulation
from tracked_kinematics.offline.bag_simulation import truth_path
from tracked_kinematics.offline.cli import (
    icr_map, identify_drivetrain, identify_icr, plan_trajectory, simulate_bag,
    tracked_kinematics_demo)
from tracked_kinematics.offline.demo_directory import MANIFEST

BIN = os.path.dirname(sys.executable)

# tool, arguments before the outputs (failing at the first step of work), file flags, bags
TOOLS = {
    'identify_icr': (identify_icr, ['no_such_bag', '--ground-truth-topic', '/gt'],
                     ['--output', '--report', '--plot'], []),
    'identify_drivetrain': (identify_drivetrain, ['no_such_bag'],
                            ['--output', '--report', '--plot'], []),
    'icr_map': (icr_map, ['no_such_vehicle'], ['--output', '--csv', '--plot'], []),
    'plan_trajectory': (plan_trajectory, ['--params', 'no_such.yaml', '--goal', '1', '0', '0'],
                        ['--csv', '--plot'], ['--bag']),
    'simulate_bag': (simulate_bag, ['--vehicle', 'no_such_vehicle', '--duration', '1'],
                     ['--truth'], ['OUT']),
}
SUFFIX = {'--plot': '.png', '--report': '.json', '--csv': '.csv'}
FILE_FLAGS = [(tool, flag) for tool, (_, _, files, _) in TOOLS.items() for flag in files]
BAG_FLAGS = [(tool, flag) for tool, (_, _, _, bags) in TOOLS.items() for flag in bags]


def listing(directory):
    """Every path under ``directory`` with its kind, size and target, for before/after."""
    found = {}
    for root, dirs, files in os.walk(directory):
        for name in dirs + files:
            path = os.path.join(root, name)
            info = os.lstat(path)
            link = os.readlink(path) if stat.S_ISLNK(info.st_mode) else None
            found[os.path.relpath(path, directory)] = (stat.S_IFMT(info.st_mode),
                                                       info.st_size, link)
    return found


def call(tool, extra, capsys):
    """Run a tool's main in-process; return its status and stderr."""
    module, base, _, _ = TOOLS[tool]
    argv = [str(a) for a in base + extra]
    if 'OUT' in extra:
        i = argv.index('OUT')
        argv = [argv[i + 1]] + argv[:i] + argv[i + 2:]
    try:
        status = module.main(argv)
    except SystemExit as exc:
        status = exc.code
    return status, capsys.readouterr().err


def output_args(tool, flag, path, tmp_path):
    """Return the flag under attack with ``path``, the tool's other required outputs fine."""
    extra = [flag, path]
    if tool in ('identify_icr', 'identify_drivetrain') and flag != '--output':
        extra += ['--output', tmp_path / 'fine.yaml']
    if tool == 'simulate_bag' and flag != 'OUT':
        extra += ['OUT', tmp_path / 'new_bag']
    return extra


def assert_refused(status, err, flag, pattern):
    assert status == 2, err
    line = err.strip()
    assert '\n' not in line and 'Traceback' not in line, err
    assert flag in line and pattern in line, line


@pytest.mark.parametrize('tool, flag', FILE_FLAGS, ids=lambda v: v)
def test_existing_file_needs_force(tool, flag, tmp_path, capsys):
    path = tmp_path / f'mine{SUFFIX.get(flag, ".yaml")}'
    path.write_text('keep me\n')
    before = listing(tmp_path)
    status, err = call(tool, output_args(tool, flag, path, tmp_path), capsys)
    assert_refused(status, err, flag, 'exists; use --force to replace it')
    assert listing(tmp_path) == before and path.read_text() == 'keep me\n'


@pytest.mark.parametrize('tool, flag', FILE_FLAGS, ids=lambda v: v)
def test_special_files_and_links_refused_even_with_force(tool, flag, tmp_path, capsys):
    target = tmp_path / 'target.yaml'
    target.write_text('target\n')
    (tmp_path / 'link').symlink_to(target)
    (tmp_path / 'dangling').symlink_to(tmp_path / 'nowhere')
    os.mkfifo(tmp_path / 'fifo')
    (tmp_path / 'dir').mkdir()
    before = listing(tmp_path)
    cases = [('/dev/null', 'a character device, not a regular file'),
             (tmp_path / 'fifo', 'a FIFO, not a regular file'),
             (tmp_path / 'link', 'is a symbolic link'),
             (tmp_path / 'dangling', 'is a symbolic link'),
             (tmp_path / 'dir', 'a directory, not a regular file'),
             (tmp_path / 'missing' / 'out.yaml', 'does not exist')]
    for path, pattern in cases:
        status, err = call(tool, output_args(tool, flag, path, tmp_path) + ['--force'],
                           capsys)
        assert_refused(status, err, flag, pattern)
    assert listing(tmp_path) == before
    assert target.read_text() == 'target\n' and not (tmp_path / 'nowhere').exists()
    assert stat.S_ISCHR(os.stat('/dev/null').st_mode)


@pytest.mark.parametrize('tool', [t for t in TOOLS if len(TOOLS[t][2]) >= 2])
def test_the_same_path_twice_is_refused(tool, tmp_path, capsys):
    flags = TOOLS[tool][2]
    path = tmp_path / 'same.yaml'
    extra = [flags[0], path, flags[1], tmp_path / '.' / 'same.yaml']
    if tool in ('identify_icr', 'identify_drivetrain') and '--output' not in flags[:2]:
        extra += ['--output', tmp_path / 'fine.yaml']
    if '--plot' in flags[:2]:
        extra = [flags[0], tmp_path / 'same.png', flags[1], tmp_path / 'same.png']
    status, err = call(tool, extra, capsys)
    assert_refused(status, err, flags[1], 'name the same file')
    assert listing(tmp_path) == {}


@pytest.mark.parametrize('tool, flag', BAG_FLAGS, ids=lambda v: v)
def test_a_bag_is_never_replaced(tool, flag, tmp_path, capsys):
    (tmp_path / 'old_bag').mkdir()
    (tmp_path / 'old_bag' / 'metadata.yaml').write_text('old\n')
    (tmp_path / 'link').symlink_to(tmp_path / 'old_bag')
    (tmp_path / 'dangling').symlink_to(tmp_path / 'nowhere')
    before = listing(tmp_path)
    for path, pattern in ((tmp_path / 'old_bag', 'exists; choose a new path for the bag'),
                          (tmp_path / 'link', 'is a symbolic link'),
                          (tmp_path / 'dangling', 'is a symbolic link'),
                          ('/dev/null', 'is a symbolic link' if os.path.islink('/dev/null')
                           else 'exists; choose a new path')):
        extra = [flag, path, '--force']
        if tool == 'simulate_bag':
            extra += ['--truth', tmp_path / 'truth.yaml']
        status, err = call(tool, extra, capsys)
        assert_refused(status, err, flag, pattern)
    assert listing(tmp_path) == before


def test_report_equal_to_output_is_refused_and_the_terrain_file_kept(tmp_path, capsys):
    out = tmp_path / 'floor.yaml'
    out.write_text('mine\n')
    status, err = call('identify_icr', ['--output', out, '--report', out, '--force'], capsys)
    assert_refused(status, err, '--report', 'name the same file')
    assert out.read_text() == 'mine\n'


@pytest.mark.parametrize('tool', ['identify_icr', 'identify_drivetrain'])
def test_an_input_bag_is_never_an_output(tool, tmp_path, capsys):
    bag = tmp_path / 'run.bag'
    bag.write_bytes(b'#ROSBAG V2.0\n')
    module, base, _, _ = TOOLS[tool]
    argv = [str(bag)] + [str(a) for a in base[1:]] + ['--output', str(tmp_path / 'o.yaml'),
                                                      '--report', str(bag), '--force']
    assert module.main(argv) == 2
    assert 'is also the input BAG' in capsys.readouterr().err
    assert bag.read_bytes() == b'#ROSBAG V2.0\n'


@pytest.mark.parametrize('tool', ['identify_icr', 'identify_drivetrain'])
def test_a_file_of_an_input_bag_is_never_an_output(tool, tmp_path, capsys):
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: {}\n')
    module, base, _, _ = TOOLS[tool]
    for flag in ('--output', '--report'):
        extra = ['--output', str(tmp_path / 'o.yaml')] if flag == '--report' else []
        argv = [str(bag)] + [str(a) for a in base[1:]] + extra
        argv += [flag, str(bag / 'metadata.yaml'), '--force']
        assert module.main(argv) == 2
        assert f'{flag} {bag / "metadata.yaml"} is inside the input BAG' in \
            capsys.readouterr().err
    assert (bag / 'metadata.yaml').read_text() == 'rosbag2_bagfile_information: {}\n'


def test_the_automatic_truth_file_is_checked_first(tmp_path, capsys):
    bag = tmp_path / 'run'
    truth_path(bag).write_text('my truth\n')
    assert simulate_bag.main([str(bag), '--duration', '1']) == 2
    err = capsys.readouterr().err
    assert 'run.truth.yaml exists; use --force' in err
    assert not bag.exists() and truth_path(bag).read_text() == 'my truth\n'


def test_dev_null_as_root_stays_a_device(tmp_path):
    # The reproduction, as a black box: a console script with --output /dev/null
    # (and --force) must neither replace /dev/null nor report success.
    done = subprocess.run([os.path.join(BIN, 'icr_map'), 'packbot', '--n', '3', '--output',
                           '/dev/null', '--force'], capture_output=True, text=True, timeout=120,
                          cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr == ('icr_map: error: --output /dev/null is a character device, not a '
                           'regular file\n')
    assert stat.S_ISCHR(os.stat('/dev/null').st_mode)
    assert done.stdout == ''   # refused before the map was computed


@pytest.mark.parametrize('make, pattern', [
    (lambda p: p.symlink_to(p.parent / 'marked'), 'is a symbolic link'),
    (lambda p: p.symlink_to(p.parent / 'nowhere'), 'is a symbolic link'),
    (lambda p: p.write_text('a file\n'), 'exists and is not a directory'),
])
def test_demo_output_directory_attacks(tmp_path, capsys, make, pattern):
    marked = tmp_path / 'marked'
    marked.mkdir()
    (marked / MANIFEST).write_text('{"entries": []}\n')
    (marked / 'thesis.yaml').write_text('keep\n')
    make(tmp_path / 'out')
    before = listing(tmp_path)
    status = tracked_kinematics_demo.main(['--output', str(tmp_path / 'out'), '--duration', '5',
                                           '--paths', '1', '--path-duration', '5'])
    err = capsys.readouterr().err
    assert_refused(status, err, '--output', pattern)
    assert listing(tmp_path) == before


@pytest.mark.parametrize('tool, target, argv', [
    ('simulate_bag', 'simulate', ['{tmp}/bag', '--vehicle', 'packbot', '--duration', '1']),
    ('icr_map', 'icr_map', ['packbot', '--n', '3', '--output', '{tmp}/o.yaml']),
    ('tracked_kinematics_demo', 'TwistTable.of', ['--output', '{tmp}/demo']),
])
def test_a_bug_is_a_traceback_and_still_leaves_nothing(tool, target, argv, tmp_path, capsys,
                                                       monkeypatch):
    # These tools caught a bare ValueError with their own format; now only the package's
    # errors are one line (run_main), a bug is a traceback, and the outputs are cleaned up.
    module = {'simulate_bag': simulate_bag, 'icr_map': icr_map,
              'tracked_kinematics_demo': tracked_kinematics_demo}[tool]
    # simulate_bag's simulation is its library's.
    where = bag_simulation if tool == 'simulate_bag' else module

    def bug(*args, **kwargs):
        raise ValueError('bug')
    *owner, name = target.split('.')
    for part in owner:
        where = getattr(where, part)
    monkeypatch.setattr(where, name, bug)
    with pytest.raises(ValueError, match='^bug$'):
        module.main([a.format(tmp=tmp_path) for a in argv])
    assert capsys.readouterr().err == ''
    assert list(tmp_path.iterdir()) == []
