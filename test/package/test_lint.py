"""ament_flake8 and ament_pep257 over the package, as in any ament_python package."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
NAMES = ('tracked_kinematics', 'test', 'launch', 'benchmarks', 'setup.py')
PATHS = [str(ROOT / name) for name in NAMES if (ROOT / name).exists()]


@pytest.mark.linter
def test_flake8():
    from ament_flake8.main import main_with_errors
    rc, errors = main_with_errors(argv=PATHS)
    assert rc == 0, f'Found {len(errors)} code style errors / warnings:\n' + '\n'.join(errors)


@pytest.mark.linter
def test_pep257():
    from ament_pep257.main import main
    rc = main(argv=[str(ROOT / 'tracked_kinematics'), str(ROOT / 'launch')])
    assert rc == 0, 'Found code style errors / warnings'
