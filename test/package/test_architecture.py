"""The three rings: imports point inwards only (STYLE.md sec. 1)."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / 'tracked_kinematics'
ROS_LIBS = ('rclpy', 'rosbags', 'nav_msgs', 'geometry_msgs', 'sensor_msgs', 'std_msgs',
            'std_srvs', 'tf2_ros', 'tf2_msgs', 'builtin_interfaces', 'rcl_interfaces',
            'launch', 'launch_ros')
# Per ring: module prefixes it must never import.
FORBIDDEN = {
    'core': ROS_LIBS + ('tracked_kinematics.offline', 'tracked_kinematics.ros',
                        'tracked_kinematics.params', 'tracked_kinematics.share', 'yaml',
                        'matplotlib'),
    'offline': ('rclpy', 'tracked_kinematics.ros', 'tf2_ros'),
    'ros': ('rosbags', 'tracked_kinematics.offline'),
}


def imported_modules(path):
    tree = ast.parse(path.read_text(), filename=str(path))
    package_parts = ['tracked_kinematics'] + list(path.relative_to(PACKAGE).parent.parts)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package_parts[:len(package_parts) - node.level + 1]
                module = '.'.join(base + ([node.module] if node.module else []))
            else:
                module = node.module
            yield node.lineno, module


def ring_files():
    for ring in FORBIDDEN:
        for path in sorted((PACKAGE / ring).rglob('*.py')):
            yield pytest.param(ring, path, id=str(path.relative_to(PACKAGE)))


@pytest.mark.parametrize('ring, path', list(ring_files()))
def test_imports_point_inwards(ring, path):
    bad = [f'{path.name}:{line} imports {module}'
           for line, module in imported_modules(path)
           if any(module == f or module.startswith(f + '.') for f in FORBIDDEN[ring])]
    assert not bad, f'{ring}/ must not import these: {bad}'


def test_checker_catches_a_wrong_arrow():
    # The test above must be able to fail: a core module importing rclpy is caught.
    fake = PACKAGE / 'core' / '_probe_wrong_arrow.py'
    fake.write_text('import rclpy\nfrom ..ros import something\n')
    try:
        found = [m for _, m in imported_modules(fake)]
    finally:
        fake.unlink()
    assert found == ['rclpy', 'tracked_kinematics.ros']
    assert any(m.startswith(f) for m in found for f in FORBIDDEN['core'])
