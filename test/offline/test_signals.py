"""
Signals in the offline tools, in-process: each window a signal could once land in (issue 20).

The signal is raised in this thread (``signal.raise_signal``: ``os.kill`` to the process may
be delivered to another of its threads, a DDS thread of an earlier test) at the exact step;
Python runs the handler at the next bytecode, so each test places it where the old code lost
track of a file. test_stop_at_any_instant.py does the same from outside, at instants spread
over the tools' lives.
"""

import json
import signal
import subprocess
import sys
import time

import pytest
from tracked_kinematics.offline import outputs as outputs_module
from tracked_kinematics.offline import signals
from tracked_kinematics.offline.cli.common import run_main
from tracked_kinematics.offline.outputs import Outputs

BIN = sys.executable.rsplit('/', 1)[0]


def kill_self(signum=signal.SIGTERM):
    signal.raise_signal(signum)


def signal_after(monkeypatch, owner, name, signum=signal.SIGTERM):
    """Make ``owner.name`` send ``signum`` to this process just after the real one returns."""
    real = getattr(owner, name)

    def then_signal(*args, **kwargs):
        result = real(*args, **kwargs)
        kill_self(signum)
        return result
    monkeypatch.setattr(owner, name, then_signal)


def test_a_signal_right_after_the_bag_directory_is_made_removes_it(
        tmp_path, capsys, monkeypatch):
    # The cause of test_a_signal_while_writing_the_bag_leaves_nothing failing under load: the
    # exception landed in mkdtemp after its mkdir, before Outputs recorded the directory.
    signal_after(monkeypatch, outputs_module.tempfile, 'mkdtemp')

    def run(args, out):
        with Outputs() as outputs:
            outputs.add('OUT', tmp_path / 'bag', directory=True)
            with outputs.path('OUT') as tmp:
                tmp.mkdir()
            raise AssertionError('the signal did not stop the run')
    assert run_main('tool', run, None) == 143
    assert capsys.readouterr().err == 'tool: error: terminated by SIGTERM\n'
    assert list(tmp_path.iterdir()) == []


def test_a_signal_right_after_a_temporary_file_is_made_removes_it(
        tmp_path, capsys, monkeypatch):
    signal_after(monkeypatch, outputs_module.tempfile, 'mkstemp', signal.SIGINT)

    def run(args, out):
        with Outputs() as outputs:
            outputs.add('--output', tmp_path / 'o.yaml')
            outputs.write_text('--output', 'x: 1\n')
            raise AssertionError('the signal did not stop the run')
    assert run_main('tool', run, None) == 130
    assert capsys.readouterr().err == 'tool: error: interrupted\n'
    assert list(tmp_path.iterdir()) == []


def test_a_signal_between_two_renames_lets_the_commit_finish(tmp_path, capsys, monkeypatch):
    # Before: the first output was renamed, the signal landed before it was recorded as
    # done, and the run ended with one output of two at its target.
    signal_after(monkeypatch, outputs_module.os, 'replace')
    (tmp_path / 'a.yaml').write_text('old\n')

    def run(args, out):
        with Outputs(force=True) as outputs:
            for name in ('a.yaml', 'b.json'):
                outputs.add(name, tmp_path / name)
                outputs.write_text(name, f'{name}\n')
        raise AssertionError('the signal did not end the run after the commit')
    assert run_main('tool', run, None) == 143
    assert capsys.readouterr().err == 'tool: error: terminated by SIGTERM\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ['a.yaml', 'b.json']
    assert (tmp_path / 'a.yaml').read_text() == 'a.yaml\n'
    assert (tmp_path / 'b.json').read_text() == 'b.json\n'


def test_a_signal_before_the_first_rename_renames_nothing(tmp_path, capsys, monkeypatch):
    real = outputs_module.check_output

    def check_then_signal(*args, **kwargs):
        kill_self(signal.SIGINT)     # while the commit checks the targets again
        return real(*args, **kwargs)
    (tmp_path / 'a.yaml').write_text('old\n')

    def run(args, out):
        with Outputs(force=True) as outputs:
            for name in ('a.yaml', 'b.json'):
                outputs.add(name, tmp_path / name)
                outputs.write_text(name, 'new\n')
            monkeypatch.setattr(outputs_module, 'check_output', check_then_signal)
        raise AssertionError('the signal did not stop the commit')
    assert run_main('tool', run, None) == 130
    assert sorted(p.name for p in tmp_path.iterdir()) == ['a.yaml']
    assert (tmp_path / 'a.yaml').read_text() == 'old\n'


def test_what_an_exception_at_the_entry_of_exit_leaves_staged_is_removed(
        tmp_path, capsys, monkeypatch):
    # A signal can land as Outputs.__exit__ is entered, before its first line: nothing in
    # the with statement removes the staged files then; run_main's safety net does.
    def exit_interrupted(self, *exc):
        raise KeyboardInterrupt
    monkeypatch.setattr(Outputs, '__exit__', exit_interrupted)

    def run(args, out):
        with Outputs() as outputs:
            outputs.add('--output', tmp_path / 'o.yaml')
            outputs.write_text('--output', 'x: 1\n')
            outputs.add('OUT', tmp_path / 'bag', directory=True)
            with outputs.path('OUT') as tmp:
                tmp.mkdir()
                (tmp / 'metadata.yaml').write_text('x\n')
    assert run_main('tool', run, None) == 130
    assert list(tmp_path.iterdir()) == []


def test_a_signal_while_the_error_line_is_made_is_ignored(capsys):
    from tracked_kinematics.offline.errors import UsageError

    class Loud(UsageError):
        def __str__(self):
            kill_self(signal.SIGINT)    # the run's work has ended: too late to matter
            return 'bad option'

    def run(args, out):
        raise Loud()
    assert run_main('tool', run, None) == 2
    assert capsys.readouterr().err == 'tool: error: bad option\n'


def test_a_run_inside_a_run_lets_the_outer_one_report_the_signal(capsys):
    def inner(args, out):
        kill_self(signal.SIGINT)
        raise AssertionError('the signal did not stop the inner run')

    def outer(args, out):
        run_main('inner', inner, None)
        raise AssertionError('the inner run swallowed the signal')
    assert run_main('outer', outer, None) == 130
    assert capsys.readouterr().err == 'outer: error: interrupted\n'


def test_a_held_section_defers_the_signal_to_its_end(capsys):
    steps = []
    previous = signal.getsignal(signal.SIGTERM)

    def run(args, out):
        with signals.held():
            kill_self()
            steps.append('held section completed')
        steps.append('after the section')
        return 0
    assert run_main('tool', run, None) == 143
    assert steps == ['held section completed']
    assert signal.getsignal(signal.SIGTERM) is previous


def test_outside_a_run_a_held_section_holds_ctrl_c(tmp_path, monkeypatch):
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    steps = []
    with pytest.raises(KeyboardInterrupt):
        with signals.held():
            kill_self(signal.SIGINT)
            steps.append('completed')
    assert steps == ['completed']
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    # And Outputs used from a script: Ctrl-C while staging leaves nothing.
    signal_after(monkeypatch, outputs_module.tempfile, 'mkstemp', signal.SIGINT)
    with pytest.raises(KeyboardInterrupt):
        with Outputs() as outputs:
            outputs.add('--output', tmp_path / 'o.yaml')
            outputs.write_text('--output', 'x\n')
    assert list(tmp_path.iterdir()) == []


def takes_sigterm(pid):
    with open(f'/proc/{pid}/status') as stream:
        caught = next(int(line.split()[1], 16) for line in stream
                      if line.startswith('SigCgt:'))
    return bool(caught >> (signal.SIGTERM - 1) & 1)


@pytest.mark.parametrize('signum, status, reason', [
    (signal.SIGTERM, 143, 'terminated by SIGTERM'), (signal.SIGINT, 130, 'interrupted')])
def test_a_signal_during_the_imports_ends_the_tool_with_one_line(tmp_path, signum, status,
                                                                 reason):
    process = subprocess.Popen([f'{BIN}/simulate_bag', 'bag', '--vehicle', 'packbot',
                                '--duration', '2'], cwd=tmp_path, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not takes_sigterm(process.pid):   # the package has begun to import
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.001)
        process.send_signal(signum)
        process.send_signal(signum)              # an impatient second one
        _, err = process.communicate(timeout=120)
    finally:
        process.kill()
    assert (process.returncode, err) == (status, f'simulate_bag: error: {reason}\n')
    assert list(tmp_path.iterdir()) == []


def test_a_signal_while_a_demo_rerun_clears_the_previous_run_keeps_the_users_files(
        tmp_path, capsys, monkeypatch):
    from tracked_kinematics.offline import demo_directory as directory
    from tracked_kinematics.offline.cli import tracked_kinematics_demo as demo
    out = tmp_path / 'out'
    args = demo.build_parser().parse_args(['--output', str(out), '--paths', '1'])

    def steps(args, stdout, spec, terrain, overrides, outputs, start):
        """Write every planned output as the real steps would (no simulation)."""
        for entry in directory.planned_outputs(spec.name, terrain, [demo.heldout_name(0)]):
            path = outputs.directory / entry.path
            if entry.kind == 'dir':
                continue
            outputs.record(directory.Entry(entry.kind, entry.path))
            if entry.kind == 'bag':
                path.mkdir()
                (path / 'metadata.yaml').write_text('m\n')
            else:
                path.write_text('of the run\n')
            outputs.written()
        return 0
    monkeypatch.setattr(demo, '_steps', steps)
    assert demo.run(args, None) == 0
    (out / 'notes.txt').write_text('mine\n')
    (out / 'calibration' / 'mine.txt').write_text('mine too\n')
    real = directory.DemoDirectory._remove

    def remove_after_a_signal(self, entries):
        if entries:
            kill_self()
        real(self, entries)
    monkeypatch.setattr(directory.DemoDirectory, '_remove', remove_after_a_signal)
    monkeypatch.setattr(demo, '_steps', lambda *a: pytest.fail('the signal did not stop it'))
    assert run_main('tracked_kinematics_demo', demo.run, args) == 143
    assert capsys.readouterr().err == 'tracked_kinematics_demo: error: terminated by SIGTERM\n'
    # The previous outputs are gone, all of them (docs/output-files.md), the user's are not.
    left = sorted(str(p.relative_to(out)) for p in out.rglob('*'))
    assert left == [directory.MANIFEST, 'calibration', 'calibration/mine.txt', 'notes.txt']
    assert json.loads((out / directory.MANIFEST).read_text())['entries'] == []
    assert (out / 'notes.txt').read_text() == 'mine\n'


def test_a_signal_just_after_a_demo_bag_is_in_place_removes_it(tmp_path, capsys, monkeypatch):
    # Found by test_stop_at_any_instant: the held-out bag was renamed into place, the signal
    # came before the demo had listed its files, and fail() left it (and the directory).
    from tracked_kinematics.offline.cli import tracked_kinematics_demo as demo
    signal_after(monkeypatch, demo, 'heldout_path', signal.SIGINT)
    args = demo.build_parser().parse_args([
        '--output', str(tmp_path / 'demo'), '--paths', '1', '--duration', '15',
        '--path-duration', '1', '--vehicle', 'packbot', '--storage', 'sqlite3'])
    assert run_main(demo.PROG, demo.run, args) == 130
    assert capsys.readouterr().err.endswith('tracked_kinematics_demo: error: interrupted\n')
    assert list(tmp_path.iterdir()) == []
