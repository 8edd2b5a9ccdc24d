"""offline/outputs.py: output paths checked first, written atomically, all or none."""

import os
import stat

import pytest
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
            assert not tmp.exists() and tmp.parent == tmp_path
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
