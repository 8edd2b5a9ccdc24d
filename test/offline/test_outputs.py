"""offline/outputs.py: output paths checked first, written atomically, all or none."""

import contextlib
import os
import signal
import stat
import subprocess

import pytest
from tracked_kinematics.offline import outputs as outputs_module
from tracked_kinematics.offline.outputs import check_output, OutputError, Outputs


def listing(directory):
    """Names in a directory, sorted."""
    return sorted(p.name for p in directory.iterdir())


def test_new_files_committed_together(tmp_path):
    with Outputs() as out:
        out.add('--output', tmp_path / 'a.yaml')
        out.add('--report', tmp_path / 'a.json')
        out.write_text('--output', 'x: 1\n')
        out.write_text('--report', '{}\n')
        # staged beside the targets, hidden; the targets appear only at the end
        assert len(list(tmp_path.glob('.a.*.tmp-*'))) == 2 and not (tmp_path / 'a.yaml').exists()
    assert listing(tmp_path) == ['a.json', 'a.yaml']
    assert (tmp_path / 'a.yaml').read_text() == 'x: 1\n'


def test_failure_leaves_nothing_new(tmp_path):
    (tmp_path / 'old.yaml').write_text('old')
    with pytest.raises(RuntimeError):
        with Outputs(force=True) as out:
            out.add('--output', tmp_path / 'old.yaml')
            out.add('--plot', tmp_path / 'p.png')
            out.write_text('--output', 'new')
            with out.path('--plot') as tmp:
                tmp.write_bytes(b'half a png')
            raise RuntimeError('the plot failed')
    assert listing(tmp_path) == ['old.yaml']
    assert (tmp_path / 'old.yaml').read_text() == 'old'


def test_existing_file_needs_force(tmp_path):
    (tmp_path / 'a.yaml').write_text('mine')
    with pytest.raises(OutputError, match=r'--output .*a.yaml exists; use --force'):
        Outputs().add('--output', tmp_path / 'a.yaml')
    with Outputs(force=True) as out:
        out.add('--output', tmp_path / 'a.yaml')
        out.write_text('--output', 'new')
    assert (tmp_path / 'a.yaml').read_text() == 'new'


def test_file_that_appears_meanwhile_is_not_replaced(tmp_path):
    out = Outputs()
    out.add('--output', tmp_path / 'a.yaml')
    out.write_text('--output', 'ours')
    (tmp_path / 'a.yaml').write_text('someone else')
    with pytest.raises(OutputError, match='exists'):
        out.commit()
    assert (tmp_path / 'a.yaml').read_text() == 'someone else'
    assert listing(tmp_path) == ['a.yaml']


@pytest.mark.parametrize('force', [False, True])
def test_symlink_refused_and_left_alone(tmp_path, force):
    target = tmp_path / 'target.yaml'
    target.write_text('kept')
    (tmp_path / 'link.yaml').symlink_to(target)
    with pytest.raises(OutputError, match='symbolic link'):
        Outputs(force=force).add('--output', tmp_path / 'link.yaml')
    dangling = tmp_path / 'dangling.yaml'
    dangling.symlink_to(tmp_path / 'nowhere.yaml')
    with pytest.raises(OutputError, match='symbolic link'):
        Outputs(force=force).add('--output', dangling)
    assert target.read_text() == 'kept' and (tmp_path / 'link.yaml').is_symlink()
    assert not (tmp_path / 'nowhere.yaml').exists()


def test_special_files_refused(tmp_path):
    fifo = tmp_path / 'fifo'
    os.mkfifo(fifo)
    with pytest.raises(OutputError, match='a FIFO, not a regular file'):
        Outputs(force=True).add('--report', fifo)
    with pytest.raises(OutputError, match='character device'):
        Outputs(force=True).add('--output', '/dev/null')
    assert stat.S_ISCHR(os.stat('/dev/null').st_mode)
    with pytest.raises(OutputError, match='a directory'):
        Outputs(force=True).add('--output', tmp_path)


def test_same_file_twice_refused(tmp_path):
    out = Outputs()
    out.add('--output', tmp_path / 'a.yaml')
    with pytest.raises(OutputError, match='--report and --output name the same file'):
        out.add('--report', tmp_path / '.' / 'a.yaml')


def test_missing_or_read_only_directory(tmp_path):
    with pytest.raises(OutputError, match='does not exist'):
        check_output('--report', tmp_path / 'no' / 'r.json')
    ro = tmp_path / 'ro'
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if os.access(ro, os.W_OK):
            pytest.skip('running as a user who can write anywhere')
        with pytest.raises(OutputError, match='not writable'):
            check_output('--report', ro / 'r.json')
    finally:
        ro.chmod(0o700)


def test_directory_output_must_be_new_and_is_renamed_whole(tmp_path):
    (tmp_path / 'old_bag').mkdir()
    with pytest.raises(OutputError, match='exists; choose a new path'):
        Outputs(force=True).add('BAG', tmp_path / 'old_bag', directory=True)
    with Outputs() as out:
        out.add('BAG', tmp_path / 'bag', directory=True)
        with out.path('BAG') as tmp:
            # A hidden holder directory with the bag under its own name, which does not exist
            # yet: rosbags creates it (and names its files after it).
            assert not tmp.exists() and tmp.name == 'bag' and tmp.parent.parent == tmp_path
            assert tmp.parent.name.startswith('.bag.tmp-')
            tmp.mkdir()
            (tmp / 'metadata.yaml').write_text('m')
    assert listing(tmp_path) == ['bag', 'old_bag']
    assert (tmp_path / 'bag' / 'metadata.yaml').read_text() == 'm'


def test_full_disk_leaves_nothing(tmp_path, monkeypatch):
    out = Outputs()
    out.add('--report', tmp_path / 'r.json')
    real_open = open

    def full(path, mode='r', *args, **kwargs):
        stream = real_open(path, mode, *args, **kwargs)
        if 'w' in mode:
            def write(_):
                raise OSError(28, 'No space left on device')
            stream.write = write
        return stream
    monkeypatch.setattr('builtins.open', full)
    with pytest.raises(OSError, match='No space left'):
        out.write_text('--report', '{"a": 1}')
    monkeypatch.undo()
    out.commit()
    assert listing(tmp_path) == []


def test_permissions_follow_umask(tmp_path):
    old = os.umask(0o022)
    try:
        with Outputs() as out:
            out.add('--output', tmp_path / 'a.yaml')
            out.write_text('--output', 'x')
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(tmp_path / 'a.yaml').st_mode) == 0o644


def test_temporary_files_keep_the_extension_for_writers_that_read_it(tmp_path):
    out = Outputs()
    out.add('--plot', tmp_path / 'fit.png')
    with out.path('--plot') as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith('.fit.png.tmp-')
        assert tmp.suffix == '.png' and tmp.exists()
        tmp.write_bytes(b'png')
    out.commit()
    assert listing(tmp_path) == ['fit.png']


def test_a_ros1_bag_file_is_a_new_path_too(tmp_path):
    (tmp_path / 'old.bag').write_bytes(b'old')
    with pytest.raises(OutputError, match='exists; choose a new path for the bag'):
        Outputs(force=True).add('OUT', tmp_path / 'old.bag', directory=True)
    with Outputs() as out:
        out.add('OUT', tmp_path / 'run.bag', directory=True)
        with out.path('OUT') as tmp:
            assert not tmp.exists() and tmp.name == 'run.bag'
            tmp.write_bytes(b'#ROSBAG V2.0')
    assert listing(tmp_path) == ['old.bag', 'run.bag']


def test_every_target_is_checked_before_the_first_rename(tmp_path):
    out = Outputs()
    out.add('--output', tmp_path / 'a.yaml')
    out.add('--report', tmp_path / 'b.json')
    out.write_text('--output', 'a')
    out.write_text('--report', 'b')
    (tmp_path / 'b.json').symlink_to(tmp_path / 'elsewhere')   # appears meanwhile
    with pytest.raises(OutputError, match='--report .*b.json is a symbolic link'):
        out.commit()
    assert listing(tmp_path) == ['b.json']   # a.yaml was not renamed either
    assert not (tmp_path / 'elsewhere').exists()


def test_a_rename_that_fails_removes_the_new_files_renamed_before(tmp_path, monkeypatch):
    out = Outputs()
    for flag, name in (('--output', 'a.yaml'), ('--new', 'n.yaml'), ('--report', 'b.json')):
        out.add(flag, tmp_path / name)
        out.write_text(flag, f'new {flag}')
    real = os.link

    def flaky(src, dst):
        if str(dst).endswith('b.json'):
            raise FileExistsError(17, 'File exists')   # appeared at the last moment
        return real(src, dst)
    monkeypatch.setattr(os, 'link', flaky)
    with pytest.raises(OutputError, match='b.json appeared while the tool ran'):
        out.commit()
    monkeypatch.undo()
    assert listing(tmp_path) == []


def test_a_forced_replacement_is_restored_when_a_later_rename_fails(tmp_path, monkeypatch):
    (tmp_path / 'a.yaml').write_text('old a')
    out = Outputs(force=True)
    out.add('--output', tmp_path / 'a.yaml')
    out.add('--report', tmp_path / 'b.json')
    out.write_text('--output', 'new a')
    out.write_text('--report', 'new b')
    real = os.link

    def flaky(src, dst):
        if str(dst).endswith('b.json'):
            raise OSError(5, 'Input/output error')
        return real(src, dst)
    monkeypatch.setattr(os, 'link', flaky)
    monkeypatch.setattr(os, 'rename', lambda *a: (_ for _ in ()).throw(OSError(5, 'EIO')))
    with pytest.raises(OSError):
        out.commit()
    monkeypatch.undo()
    assert listing(tmp_path) == ['a.yaml']
    assert (tmp_path / 'a.yaml').read_text() == 'old a'


def test_inputs_are_not_outputs(tmp_path):
    (tmp_path / 'base.yaml').write_text('x: 1\n')
    out = Outputs(force=True)
    out.add('--output', tmp_path / 'base.yaml')
    out.add('--report', tmp_path / 'r.json')
    out.refuse_inputs('--params', [tmp_path / 'base.yaml'], allow=('--output',))
    with pytest.raises(OutputError, match='--output .*base.yaml is also the input --params'):
        out.refuse_inputs('--params', [tmp_path / 'base.yaml'])


def test_a_file_inside_an_input_bag_is_not_an_output(tmp_path):
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'metadata.yaml').write_text('m\n')
    out = Outputs(force=True)
    out.add('--report', bag / 'metadata.yaml')
    out.refuse_inputs('--params', [tmp_path / 'other.yaml'])
    with pytest.raises(OutputError, match=r'--report .*bag/metadata.yaml is inside the input '
                                          r'BAG .*bag; choose another output path'):
        out.refuse_inputs('BAG', [tmp_path / 'other', tmp_path / '.' / 'bag'])
    with pytest.raises(OutputError, match='an empty path is not a file name'):
        check_output('--output', '')


def test_an_error_inside_path_removes_the_bag_and_its_holder(tmp_path):
    out = Outputs()
    out.add('BAG', tmp_path / 'bag', directory=True)
    with pytest.raises(RuntimeError):
        with out.path('BAG') as tmp:
            tmp.mkdir()
            (tmp / 'bag.db3').write_bytes(b'half')
            raise RuntimeError('killed')
    out.commit()
    assert listing(tmp_path) == []


def test_a_hard_link_to_another_output_is_the_same_file(tmp_path):
    (tmp_path / 'a.yaml').write_text('a')
    os.link(tmp_path / 'a.yaml', tmp_path / 'b.yaml')
    out = Outputs(force=True)
    out.add('--output', tmp_path / 'a.yaml')
    with pytest.raises(OutputError, match='--report and --output name the same file'):
        out.add('--report', tmp_path / 'b.yaml')


def test_a_name_too_long_for_its_temporary_file_is_refused_first(tmp_path):
    # A valid name, but the start check's .NAME.tmp-check-XXXXXXXX.yaml is not.
    name = 'x' * 240 + '.yaml'
    with pytest.raises(OutputError, match='the file name is too long for its temporary file '
                                          r'\(at most 230 bytes here\)'):
        check_output('--output', tmp_path / name)
    check_output('--output', tmp_path / ('x' * 225 + '.yaml'))


# The start check creates a file where the output will be staged (issue 27 item 8): os.access
# said yes to root for /proc and /sys, and the write failed only after the whole run.
@pytest.mark.parametrize('path', ['/proc/x.yaml', '/proc/self/x.yaml', '/sys/x.yaml'])
def test_a_directory_that_takes_no_file_is_refused_at_start(path):
    with pytest.raises(OutputError, match=r'^--output .*: directory /\w+.* is not writable '
                       r'\(creating a file there: '):
        Outputs(force=True).add('--output', path)


@pytest.mark.parametrize('directory', [False, True])
def test_the_start_check_leaves_nothing(tmp_path, directory):
    Outputs().add('--output', tmp_path / 'a.yaml', directory=directory)
    assert listing(tmp_path) == []


def test_the_start_check_leaves_nothing_when_its_write_fails(tmp_path, monkeypatch):
    def full(fd, data):
        raise OSError(28, 'No space left on device')
    monkeypatch.setattr(outputs_module.os, 'write', full)
    with pytest.raises(OutputError, match=r'is full \(creating a file there: No space left'):
        Outputs().add('--output', tmp_path / 'a.yaml')
    assert listing(tmp_path) == []


def test_a_signal_during_the_start_check_leaves_nothing(tmp_path, monkeypatch):
    # Ctrl-C right after the file was made: held until it is removed again.
    real = outputs_module.tempfile.mkstemp

    def then_interrupt(*args, **kwargs):
        made = real(*args, **kwargs)
        signal.raise_signal(signal.SIGINT)
        return made
    monkeypatch.setattr(outputs_module.tempfile, 'mkstemp', then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        Outputs().add('--output', tmp_path / 'a.yaml')
    assert listing(tmp_path) == []


@contextlib.contextmanager
def tmpfs(where, options):
    """Mount a small tmpfs at ``where`` (root only; skip where mounting is not allowed)."""
    where.mkdir()
    if os.geteuid() != 0 or subprocess.run(
            ['mount', '-t', 'tmpfs', '-o', options, 'tmpfs', str(where)],
            capture_output=True).returncode != 0:
        pytest.skip('cannot mount a tmpfs here')
    try:
        yield where
    finally:
        subprocess.run(['umount', '-l', str(where)], check=True)


def test_a_full_or_read_only_file_system_is_refused_at_start(tmp_path):
    with tmpfs(tmp_path / 'full', 'size=64k') as full:
        with open(full / 'filler', 'wb') as filler:
            with contextlib.suppress(OSError):
                filler.write(bytes(1 << 20))
        with pytest.raises(OutputError, match=r'directory .*full is full \(creating a file '
                           r'there: No space left on device\)'):
            Outputs().add('--output', full / 'a.yaml')
        assert listing(full) == ['filler']
    with tmpfs(tmp_path / 'ro', 'size=64k,ro') as read_only:
        with pytest.raises(OutputError, match=r'is not writable \(creating a file there: '
                           r'Read-only file system\)'):
            Outputs().add('--output', read_only / 'a.yaml')
