"""The README's main job runs on the built-in data."""

from pathlib import Path
import subprocess
import sys

from tracked_kinematics.offline import demo

BIN = Path(sys.executable).parent


def test_demo_prints_error_table(capsys):
    assert demo.main([]) == 0
    out = capsys.readouterr().out
    assert 'chi = 0.540' in out
    assert 'ideal differential drive' in out and 'constant ICRs' in out


def test_demo_console_script(tmp_path):
    result = subprocess.run([str(BIN / 'tracked_kinematics_demo')], cwd=tmp_path,
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert 'final position error' in result.stdout


def test_demo_bad_params_file_is_one_line_error(tmp_path, capsys):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('/**:\n  ros__parameters:\n    icr: {y_left: -1.0}\n')
    assert demo.main(['--params', str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith('tracked_kinematics_demo: ') and '\n' not in err
    assert 'icr.y_left' in err
