"""The rings: imports point inwards only (STYLE.md sec. 1; README "Layout")."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / 'tracked_kinematics'
ROS_LIBS = ('rclpy', 'rosbags', 'nav_msgs', 'geometry_msgs', 'sensor_msgs', 'std_msgs',
            'std_srvs', 'tf2_ros', 'tf2_msgs', 'builtin_interfaces', 'rcl_interfaces',
            'launch', 'launch_ros')
PKG = 'tracked_kinematics'
CORE_JOBS = tuple(f'{PKG}.core.{job}'
                  for job in ('identify', 'estimate', 'sim', 'plan', 'evaluate'))
# Per ring (a folder of the package, most specific first): module prefixes it must never
# import. A module obeys every rule whose folder contains it.
APPS = f'{PKG}.apps'
FORBIDDEN = {
    'core': ROS_LIBS + (f'{PKG}.offline', f'{PKG}.ros', f'{PKG}.params', f'{PKG}.share',
                        APPS, 'yaml', 'matplotlib'),
    # The core's foundation knows none of the jobs built on it.
    'core/.': CORE_JOBS,
    # Identification fits models to data; it never needs the simulator, the planner or the
    # estimator (the estimator builds on identification, not the other way round).
    'core/identify': (f'{PKG}.core.sim', f'{PKG}.core.plan', f'{PKG}.core.estimate',
                      f'{PKG}.core.evaluate'),
    'core/sim': (f'{PKG}.core.identify', f'{PKG}.core.plan', f'{PKG}.core.estimate',
                 f'{PKG}.core.evaluate'),
    'core/plan': (f'{PKG}.core.identify', f'{PKG}.core.sim', f'{PKG}.core.estimate',
                  f'{PKG}.core.evaluate'),
    'core/estimate': (f'{PKG}.core.sim', f'{PKG}.core.plan', f'{PKG}.core.evaluate'),
    # Evaluation scores what identification and estimation produce, on recorded data.
    'core/evaluate': (f'{PKG}.core.sim', f'{PKG}.core.plan'),
    'params': ROS_LIBS + (f'{PKG}.offline', f'{PKG}.ros', APPS, 'matplotlib'),
    'offline': ('rclpy', f'{PKG}.ros', 'tf2_ros', APPS),
    # Reading and writing bags is a library the command lines use, never the reverse.
    'offline/bags': (f'{PKG}.offline.cli',),
    # So is identify_icr's library: recordings in, the report out (its CLI prints and writes).
    'offline/identification': (f'{PKG}.offline.cli',),
    # So is the diff_drive_controller converter: controllers files in, parameter files out.
    'offline/ddc': (f'{PKG}.offline.cli', f'{PKG}.offline.bags', 'rosbags'),
    'ros': ('rosbags', f'{PKG}.offline', APPS),
    # The composition roots: console scripts that join a node of ros/ and the file code of
    # offline/ (calibration_drive). They may import every ring; no ring imports them, and
    # they import no third-party ROS or bag library themselves beyond rclpy's signals.
    'apps': ('rosbags', 'nav_msgs', 'geometry_msgs', 'sensor_msgs', 'std_msgs', 'std_srvs'),
}


def package_parts_of(path: Path):
    """Dotted package of a module file of the package, as a list of names."""
    return [PKG] + list(path.relative_to(PACKAGE).parent.parts)


def imported_modules(path: Path, package_parts):
    """Yield (line, absolute module) for every import of ``path``; relative ones resolved."""
    tree = ast.parse(path.read_text(), filename=str(path))
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


def rules_for(path: Path):
    """Yield the rings that ``path`` belongs to."""
    rel = path.relative_to(PACKAGE)
    for ring in FORBIDDEN:
        if ring.endswith('/.'):
            if rel.parent == Path(ring[:-2]):
                yield ring
        elif rel.parts[:len(Path(ring).parts)] == Path(ring).parts:
            yield ring


def violations(path: Path, package_parts, rings):
    """Return the imports of ``path`` that break a rule of ``rings``."""
    return [f'{path.name}:{line} imports {module} ({ring}/ must not)'
            for line, module in imported_modules(path, package_parts)
            for ring in rings
            if any(module == f or module.startswith(f + '.') for f in FORBIDDEN[ring])]


def module_files():
    for path in sorted(PACKAGE.rglob('*.py')):
        rings = list(rules_for(path))
        if rings:
            yield pytest.param(path, rings, id=str(path.relative_to(PACKAGE)))


@pytest.mark.parametrize('path, rings', list(module_files()))
def test_imports_point_inwards(path, rings):
    assert not violations(path, package_parts_of(path), rings)


def test_every_ring_has_modules():
    # A renamed folder must not silently leave its rule checking nothing.
    for ring in FORBIDDEN:
        folder = PACKAGE / ring.rstrip('/.')
        assert list(folder.glob('*.py')), ring


@pytest.mark.parametrize('rel, source, ring', [
    ('core/odometry.py', 'import rclpy\nfrom ..ros import something\n', 'core'),
    ('core/odometry.py', 'from .identify import fit\n', 'core/.'),
    ('core/identify/fit.py', 'from ..sim.dynamics import Vehicle\n', 'core/identify'),
    ('offline/bags/reader.py', 'from tracked_kinematics.offline.cli import common\n',
     'offline/bags'),
    ('params/tables.py', 'from tracked_kinematics.ros import odometry_node\n', 'params'),
    ('ros/calibration_drive.py', 'from tracked_kinematics.apps import calibration_drive\n',
     'ros'),
    ('offline/cli/identify_icr.py', 'from ...apps import calibration_drive\n', 'offline'),
])
def test_checker_catches_a_wrong_arrow(tmp_path, rel, source, ring):
    # The test above must be able to fail: a module as if at ``rel`` with a wrong import
    # is caught. The probe lives in tmp_path, never in the package source.
    probe = tmp_path / 'probe.py'
    probe.write_text(source)
    where = PACKAGE / rel
    rings = list(rules_for(where))
    assert ring in rings
    assert violations(probe, package_parts_of(where), rings)


def test_a_right_arrow_is_allowed(tmp_path):
    probe = tmp_path / 'probe.py'
    probe.write_text('from ..kinematics import IcrParams\nimport numpy as np\n')
    where = PACKAGE / 'core' / 'identify' / 'fit.py'
    assert not violations(probe, package_parts_of(where), list(rules_for(where)))


# Tools call libraries, never each other's command lines (STYLE.md sec. 2) ---------------------

CLI = f'{PKG}.offline.cli'
SETUP = PACKAGE.parent / 'setup.py'
RUNNERS = ('subprocess.run', 'subprocess.Popen', 'subprocess.call', 'subprocess.check_call',
           'subprocess.check_output', 'os.system', 'os.popen', 'os.exec', 'os.spawn',
           'os.posix_spawn', 'asyncio.create_subprocess_exec',
           'asyncio.create_subprocess_shell')


def console_scripts():
    """Return ``{script name: module}`` of setup.py's console_scripts entry points."""
    scripts = {}
    for node in ast.walk(ast.parse(SETUP.read_text())):
        # 'name = module:function' (implicitly concatenated strings are one constant).
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            name, sep, target = node.value.partition('=')
            if sep and ':' in target:
                scripts[name.strip()] = target.split(':')[0].strip()
    return scripts


SCRIPTS = console_scripts()
ENTRY_MODULES = set(SCRIPTS.values())


def module_name(path: Path) -> str:
    return '.'.join(package_parts_of(path) + [path.stem])


def _dotted(node) -> str:
    """``a.b.c`` of a Name/Attribute chain, or ''."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        parts.append(node.id)
        return '.'.join(reversed(parts))
    return ''


def _strings(node):
    return [n.value for n in ast.walk(node)
            if isinstance(n, ast.Constant) and isinstance(n.value, str)]


def command_line_calls(source: str, package_parts, name: str):
    """
    Return where a module runs another tool's command line.

    A process started on a console script of setup.py or on ``-m tracked_kinematics...``;
    a list of arguments ``['-m', 'tracked_kinematics...']`` anywhere; a call of the ``main``
    of a command-line module other than the module itself.
    """
    tree = ast.parse(source)
    found = []
    cli_aliases = {}     # local name -> cli module, for ``x.main()``
    main_aliases = {}    # local name -> cli module, for ``main()`` imported from it
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith(CLI + '.'):
                    cli_aliases[alias.asname or alias.name] = alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package_parts[:len(package_parts) - node.level + 1]
                module = '.'.join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ''
            for alias in node.names:
                full = f'{module}.{alias.name}'
                if full.startswith(CLI + '.') and module == CLI:
                    cli_aliases[alias.asname or alias.name] = full
                elif module.startswith(CLI + '.') and alias.name == 'main':
                    main_aliases[alias.asname or alias.name] = module
    for node in ast.walk(tree):
        if isinstance(node, (ast.List, ast.Tuple)):
            items = [e.value if isinstance(e, ast.Constant) else None for e in node.elts]
            for a, b in zip(items, items[1:]):
                if a == '-m' and isinstance(b, str) and b.startswith(PKG):
                    found.append(f'line {node.lineno}: runs -m {b}')
        if not isinstance(node, ast.Call):
            continue
        func = _dotted(node.func)
        if any(func == r or (r.endswith(('exec', 'spawn')) and func.startswith(r))
               for r in RUNNERS):
            for text in _strings(node):
                if text in SCRIPTS or text.startswith(f'{PKG}.') or \
                        text.split('/')[-1] in SCRIPTS:
                    found.append(f'line {node.lineno}: {func} runs {text}')
        target = None
        if func.endswith('.main') and func[:-len('.main')] in cli_aliases:
            target = cli_aliases[func[:-len('.main')]]
        elif func in main_aliases:
            target = main_aliases[func]
        if target and target != name:
            found.append(f'line {node.lineno}: calls {target}.main')
    return found


def cli_imports(source: str, package_parts, name: str):
    """Return the imports of the command lines by a module that is neither one nor a script."""
    if name.startswith(CLI + '.') or name in ENTRY_MODULES:
        return []
    probe = ast.parse(source)
    found = []
    for node in ast.walk(probe):
        modules = []
        if isinstance(node, ast.Import):
            modules = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package_parts[:len(package_parts) - node.level + 1]
                modules = ['.'.join(base + ([node.module] if node.module else []))]
            else:
                modules = [node.module or '']
        found += [f'line {node.lineno}: imports {m}' for m in modules
                  if m == CLI or m.startswith(CLI + '.')]
    return found


def test_setup_declares_the_entry_points_read_here():
    # A change of setup.py's layout must not leave the checks below without scripts.
    assert SCRIPTS['identify_icr'] == f'{CLI}.identify_icr'
    assert SCRIPTS['calibration_drive'] == f'{PKG}.apps.calibration_drive'


@pytest.mark.parametrize('path', sorted(PACKAGE.rglob('*.py')),
                         ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_tool_runs_another_tools_command_line(path):
    source = path.read_text()
    parts, name = package_parts_of(path), module_name(path)
    assert not command_line_calls(source, parts, name)
    assert not cli_imports(source, parts, name)


@pytest.mark.parametrize('rel, source', [
    # What calibration_drive's finisher did before the fit API.
    ('offline/calibration_files.py',
     "import subprocess, sys\nsubprocess.Popen([sys.executable, '-m', "
     "'tracked_kinematics.offline.cli.identify_icr', *argv])\n"),
    ('offline/calibration_files.py', "argv = [sys.executable, '-m', "
     "'tracked_kinematics.offline.cli.identify_icr']\n"),
    ('offline/calibration_files.py', "import subprocess\nsubprocess.run(['identify_icr', bag])\n"),
    ('offline/planning.py', "import os\nos.execvp('evaluate_model', ['evaluate_model'])\n"),
    # What the demo did: another command line's main.
    ('offline/cli/tracked_kinematics_demo.py',
     'from tracked_kinematics.offline.cli import identify_icr\nidentify_icr.main(argv)\n'),
    ('offline/cli/tracked_kinematics_demo.py',
     'from .identify_icr import main\nmain(argv)\n'),
])
def test_the_command_line_check_catches_a_tool_running_another(rel, source):
    where = PACKAGE / rel
    assert command_line_calls(source, package_parts_of(where), module_name(where))


@pytest.mark.parametrize('rel, source', [
    ('offline/calibration_files.py', 'from tracked_kinematics.offline.cli import identify_icr\n'),
    ('offline/demo_directory.py', 'from .cli.common import run_main\n'),
    ('apps/not_a_script.py', 'import tracked_kinematics.offline.cli.common\n'),
])
def test_the_import_check_catches_a_library_importing_a_command_line(rel, source):
    where = PACKAGE / rel
    assert cli_imports(source, package_parts_of(where), module_name(where))


def test_a_command_line_may_import_its_siblings_and_run_its_own_main():
    where = PACKAGE / 'offline' / 'cli' / 'identify_icr.py'
    source = ('from tracked_kinematics.offline.cli.common import run_main\n'
              'def main():\n    return run_main()\nmain()\n')
    name = module_name(where)
    assert not cli_imports(source, package_parts_of(where), name)
    assert not command_line_calls(source, package_parts_of(where), name)
