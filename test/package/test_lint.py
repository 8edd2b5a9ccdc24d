"""ament_flake8 and ament_pep257 over the package, as in any ament_python package."""

from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[2]
NAMES = ('tracked_kinematics', 'test', 'launch', 'benchmarks', 'setup.py')
PATHS = [str(ROOT / name) for name in NAMES if (ROOT / name).exists()]


@pytest.mark.linter
def test_flake8():
    # In a process of its own: flake8 forks its workers, and a fork of this process, whose
    # DDS threads (from ROS tests run before) may hold locks, can deadlock in the child.
    result = subprocess.run([sys.executable, '-m', 'ament_flake8.main', *PATHS],
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.linter
def test_pep257():
    from ament_pep257.main import main
    rc = main(argv=[str(ROOT / 'tracked_kinematics'), str(ROOT / 'launch')])
    assert rc == 0, 'Found code style errors / warnings'
