"""run_main: the package's errors are one line and a status; anything else is a traceback."""

import errno
import json
import re
import signal
import subprocess
import sys

import numpy as np
import pytest
from tracked_kinematics.core.errors import (
    ExcitationError, FitError, IdentificationError, InvalidParameters, PlanningError,
    TrackedKinematicsError)
from tracked_kinematics.offline.cli.common import (
    EXIT_EXCITATION, EXIT_FIT, EXIT_INPUT, run_main)
from tracked_kinematics.offline.errors import BagError, UsageError


def raising(error):
    def run(args, out):
        raise error
    return run


@pytest.mark.parametrize('error, status', [
    (BagError('bag not found: x'), EXIT_INPUT),
    (UsageError('--holdout must be in [0, 1)'), EXIT_INPUT),
    (InvalidParameters('base.yaml: not valid YAML (...)'), EXIT_INPUT),
    (TrackedKinematicsError('no segments'), EXIT_INPUT),
    (PlanningError('goal out of reach'), EXIT_INPUT),
    (FileNotFoundError(errno.ENOENT, 'No such file or directory', 'o/x.yaml'), EXIT_INPUT),
    (ExcitationError('too little turning\nto identify icr.x'), EXIT_EXCITATION),
    (FitError('did not converge'), EXIT_FIT),
    (IdentificationError('chi outside (0, 1]'), EXIT_FIT),
    (KeyboardInterrupt(), 130),
])
def test_package_errors_are_one_line_with_their_status(capsys, error, status):
    assert run_main('tool', raising(error), None) == status
    err = capsys.readouterr().err
    assert err.startswith('tool: error: ') and err.count('\n') == 1
    assert 'Traceback' not in err


def test_the_user_errors_derive_from_the_package_base():
    for kind in (BagError, UsageError, InvalidParameters):
        assert issubclass(kind, TrackedKinematicsError) and issubclass(kind, ValueError)


@pytest.mark.parametrize('bug', [ValueError('bug'), TypeError('bug'), KeyError('bug'),
                                 ZeroDivisionError('bug')])
def test_a_bug_is_not_reported_as_bad_input(capsys, bug):
    with pytest.raises(type(bug), match='bug'):
        run_main('tool', raising(bug), None)
    assert capsys.readouterr().err == ''


def test_success_returns_runs_status():
    assert run_main('tool', lambda args, out: 0, None) == 0


def test_a_bug_in_core_is_a_traceback_a_user_error_is_status_2(tmp_path):
    # A console script: a plain ValueError from the core exits 1 with its traceback; a bad
    # parameter file named by the user exits 2 with one line.
    bad = tmp_path / 'base.yaml'
    bad.write_text('a: [1, 2\n')
    script = (
        'import sys\n'
        'from tracked_kinematics.offline import tooling\n'
        'from tracked_kinematics.offline.cli import identify_icr\n'
        'def bug(*args, **kwargs):\n'
        '    raise ValueError("bug")\n'
        'tooling.read_params_file = bug if sys.argv[1] == "bug" else tooling.read_params_file\n'
        'sys.exit(identify_icr.main(["run", "--ground-truth-topic", "/gt", "-o", '
        f'{str(tmp_path / "o.yaml")!r}, "--params", {str(bad)!r}]))\n')
    done = {kind: subprocess.run([sys.executable, '-c', script, kind], capture_output=True,
                                 text=True, timeout=60) for kind in ('bug', 'user')}
    assert done['bug'].returncode == 1
    assert 'Traceback' in done['bug'].stderr and 'ValueError: bug' in done['bug'].stderr
    assert done['user'].returncode == EXIT_INPUT
    assert done['user'].stderr.startswith(f'identify_icr: error: {bad}: not valid YAML')
    assert done['user'].stderr.count('\n') == 1
    assert not (tmp_path / 'o.yaml').exists()


def test_bounded_numbers():
    import argparse
    from tracked_kinematics.offline.cli.common import bounded
    seconds = bounded(0.01, 600.0, 's', zero=True)
    assert seconds('0') == 0 and seconds('0.01') == 0.01 and seconds('600') == 600.0
    assert seconds.words == 'in [0.01, 600] s or 0'
    for text, message in (('1e-12', 'must be in [0.01, 600] s or 0, got 1e-12'),
                          ('nan', 'must be a finite number in [0.01, 600] s or 0, got nan'),
                          ('inf', 'must be a finite number in'), ('abc', 'expected a number')):
        with pytest.raises(argparse.ArgumentTypeError, match=re.escape(message)):
            seconds(text)
    count = bounded(2, 101, integer=True)
    assert count('7') == 7
    with pytest.raises(argparse.ArgumentTypeError, match=r'must be in \[2, 101\], got 100000'):
        count('100000')
    with pytest.raises(argparse.ArgumentTypeError, match='expected a whole number'):
        count('7.0')


def test_a_usage_error_is_one_line_exit_2(capsys):
    from tracked_kinematics.offline.cli.common import ArgumentParser, bounded
    parser = ArgumentParser(prog='tool')
    parser.add_argument('--n', type=bounded(2, 10, integer=True))
    parser.add_argument('--need', required=True)
    with pytest.raises(SystemExit) as exc:
        parser.parse_args(['--n', '1000', '--need', 'x'])
    assert exc.value.code == 2
    assert capsys.readouterr().err == ('tool: error: argument --n: must be in [2, 10], got '
                                       '1000 (see tool --help)\n')


@pytest.mark.parametrize('signum, status, message', [
    (signal.SIGTERM, 143, 'terminated by SIGTERM'), (signal.SIGHUP, 129, 'terminated by SIGHUP'),
    (signal.SIGINT, 130, 'interrupted')])
def test_a_signal_removes_what_was_staged(tmp_path, capsys, signum, status, message):
    # In-process: the signal arrives while an output is staged; Outputs removes it and the
    # tool reports one line with 128 + the signal.
    from tracked_kinematics.offline.outputs import Outputs

    def run(args, out):
        with Outputs() as outputs:
            outputs.add('--output', tmp_path / 'o.yaml')
            outputs.write_text('--output', 'x: 1\n')
            signal.raise_signal(signum)
            raise AssertionError('the signal did not arrive')
    previous = signal.getsignal(signal.SIGTERM)
    assert run_main('tool', run, None) == status
    assert capsys.readouterr().err == f'tool: error: {message}\n'
    assert list(tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) is previous   # handlers restored


def test_write_report_goes_through_outputs(tmp_path):
    import numpy as np
    from tracked_kinematics.offline.cli.common import write_report
    from tracked_kinematics.offline.outputs import OutputError
    path = tmp_path / 'r.json'
    write_report(path, {'a': np.arange(2), 'b': np.float64(0.5)})
    assert path.read_text() == '{\n  "a": [\n    0,\n    1\n  ],\n  "b": 0.5\n}\n'
    with pytest.raises(OutputError, match='exists; use --force'):
        write_report(path, {})
    write_report(path, {}, force=True)
    assert path.read_text() == '{}\n'


def test_a_second_signal_does_not_interrupt_the_clean_up(tmp_path, capsys, monkeypatch):
    from tracked_kinematics.offline import outputs as outputs_module
    from tracked_kinematics.offline.outputs import Outputs
    real = outputs_module._discard

    def discard_after_another_signal(tmp, directory):
        signal.raise_signal(signal.SIGINT)   # impatient Ctrl-C during the clean-up
        real(tmp, directory)
    monkeypatch.setattr(outputs_module, '_discard', discard_after_another_signal)

    def run(args, out):
        with Outputs() as outputs:
            for name in ('a.yaml', 'b.json'):
                outputs.add(name, tmp_path / name)
                outputs.write_text(name, 'x')
            signal.raise_signal(signal.SIGTERM)
    assert run_main('tool', run, None) == 143
    assert capsys.readouterr().err == 'tool: error: terminated by SIGTERM\n'
    assert list(tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_window_selection_options_default_to_the_moving_windows_of_the_core():
    from tracked_kinematics.core.identify.procedure import MIN_SPEED
    from tracked_kinematics.offline.cli import common
    parser = common.ArgumentParser(prog='tool')
    common.add_window_selection_arguments(parser)
    assert common.min_speed(parser.parse_args([])) == MIN_SPEED == common.MIN_SPEED
    assert common.min_speed(parser.parse_args(['--min-speed', '0.3'])) == 0.3
    assert common.min_speed(parser.parse_args(['--all-windows', '--min-speed', '0.3'])) is None


def test_a_report_is_strict_json_whatever_its_numbers():
    # A score with nothing to score was written as NaN or Infinity (identify_icr's
    # choice.pose_alone_m once): no JSON, which strict parsers (jq, JavaScript) refuse.
    from tracked_kinematics.offline.tooling import report_json
    text = report_json({'inf': float('inf'), 'nan': np.float64('nan'), 'n': np.int64(3),
                        'ok': np.bool_(True), 'rows': np.array([1.5, -np.inf]),
                        'nested': [{'x': (np.float32(0.25), None)}]})
    assert json.loads(text, parse_constant=lambda name: pytest.fail(name)) == {
        'inf': None, 'nan': None, 'n': 3, 'ok': True, 'rows': [1.5, None],
        'nested': [{'x': [0.25, None]}]}
