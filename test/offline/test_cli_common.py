"""run_main: the package's errors are one line and a status; anything else is a traceback."""

import errno
import subprocess
import sys

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
        'from tracked_kinematics.offline.cli import identify_icr\n'
        'def bug(*args, **kwargs):\n'
        '    raise ValueError("bug")\n'
        'identify_icr.read_params_file = bug if sys.argv[1] == "bug" else '
        'identify_icr.read_params_file\n'
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
