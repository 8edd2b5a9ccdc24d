"""
The package's layout, kept by tests (README "Layout").

Imports point inwards only: core/ imports neither params/, offline/ nor ros/; offline/ and
ros/ import core/ and params/, never each other. No module takes another module's
underscore names, no two modules share a name, nothing but the console-script
entry points imports offline/cli/, and no tool runs another tool's command line.
"""

import ast
import io
from pathlib import Path
import tokenize

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
    ('ros/calibration_drive_node.py', 'from tracked_kinematics.apps import calibration_drive\n',
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


# One module's private names stay its own: a name another module of the package needs is
# public (no leading underscore), or lives where both use it. A private module (``_checks``)
# may be imported: its underscore says "not for users", not "not for the package".

def _is_module(module: str, name: str) -> bool:
    """Whether ``module.name`` is a module or a package of the package."""
    parts = f'{module}.{name}'.split('.')
    if parts[0] != PKG:
        return False
    path = PACKAGE.joinpath(*parts[1:])
    return path.with_suffix('.py').is_file() or (path / '__init__.py').is_file()


def private_imports(path: Path, package_parts):
    """Return the underscore names ``path`` takes from another module of the package."""
    tree = ast.parse(path.read_text(), filename=str(path))
    modules = {}   # local name -> module of the package it stands for
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package_parts[:len(package_parts) - node.level + 1]
                module = '.'.join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ''
            if module != PKG and not module.startswith(PKG + '.'):
                continue
            for alias in node.names:
                if _is_module(module, alias.name):
                    modules[alias.asname or alias.name] = f'{module}.{alias.name}'
                elif alias.name.startswith('_') and not alias.name.startswith('__'):
                    found.append(f'{path.name}:{node.lineno} imports {alias.name} from {module}')
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith(PKG + '.') and alias.asname:
                    modules[alias.asname] = alias.name
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in modules and node.attr.startswith('_')
                and not node.attr.startswith('__')):
            found.append(f'{path.name}:{node.lineno} uses {modules[node.value.id]}.{node.attr}')
    return found


@pytest.mark.parametrize('path', [pytest.param(p, id=str(p.relative_to(PACKAGE)))
                                  for p in sorted(PACKAGE.rglob('*.py'))])
def test_no_private_name_crosses_modules(path):
    assert not private_imports(path, package_parts_of(path))


@pytest.mark.parametrize('source', [
    'from .heading_fit import _Heading\n',
    'from tracked_kinematics.offline.bags.opening import _connections\n',
    'from . import recordings\nrecordings._clean_gyro(None)\n',
    'from .. import reference as ref\nref._fit(None)\n',
])
def test_private_import_checker_can_fail(tmp_path, source):
    probe = tmp_path / 'probe.py'
    probe.write_text(source)
    where = PACKAGE / 'core' / 'identify' / 'reference' / 'calibration.py'
    assert private_imports(probe, package_parts_of(where))


def test_private_import_checker_allows_public_names_and_private_modules(tmp_path):
    probe = tmp_path / 'probe.py'
    probe.write_text('from ..._checks import require_numbers\nfrom ... import _checks\n'
                     'from .heading_fit import HeadingFit\nimport numpy as np\nnp._x\n'
                     'from os import _exit\n')
    where = PACKAGE / 'core' / 'identify' / 'reference' / 'calibration.py'
    assert not private_imports(probe, package_parts_of(where))


# One meaning per module name: no two modules (or sub-packages) of the package share a stem,
# so that ``prediction`` or ``evaluation`` names one thing wherever it is read. Exempt: the
# ``__init__`` files, the console scripts of offline/cli/ (named after their executables), and
# ``errors`` at the top of a ring (core/errors.py, offline/errors.py): each ring's error
# types, one meaning.
RING_STEMS = {'errors'}


def module_stems(root: Path):
    """Return {stem: [paths]} of the modules and sub-packages under ``root``."""
    stems = {}
    for path in sorted(root.rglob('*.py')):
        rel = path.relative_to(root)
        if path.name == '__init__.py':
            if rel.parent != Path('.'):
                stems.setdefault(rel.parent.name, []).append(str(rel.parent) + '/')
            continue
        if rel.parts[:2] == ('offline', 'cli'):
            continue
        if path.stem in RING_STEMS and len(rel.parts) == 2:
            # The rings' files of that name count as one module.
            ring_files = [p for p in stems.get(path.stem, []) if p.count('/') == 1]
            if ring_files:
                continue
        stems.setdefault(path.stem, []).append(str(rel))
    return stems


def shared_stems(root: Path):
    return {stem: paths for stem, paths in module_stems(root).items() if len(paths) > 1}


def test_no_two_modules_share_a_name():
    assert not shared_stems(PACKAGE)


@pytest.mark.parametrize('files, shared', [
    (('core/prediction.py', 'core/evaluate/prediction.py'), 'prediction'),
    (('core/identify/ddc.py', 'offline/ddc/__init__.py'), 'ddc'),
    (('core/errors.py', 'core/identify/errors.py'), 'errors'),
])
def test_shared_name_checker_can_fail(tmp_path, files, shared):
    for rel in files:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text('')
    assert list(shared_stems(tmp_path)) == [shared]


def test_shared_name_checker_exemptions(tmp_path):
    for rel in ('core/__init__.py', 'offline/__init__.py', 'offline/cli/__init__.py',
                'offline/cli/identify_icr.py', 'offline/identify_icr.py', 'core/errors.py',
                'offline/errors.py'):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text('')
    assert not shared_stems(tmp_path)


# Tools call libraries, never each other's command lines

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


# No import circle: a module never needs, however indirectly, a module that needs it. Every
# import counts, those inside functions too (a lazy import only hides a circle until the day
# the order of the first imports changes).

def module_imports(path: Path, root: Path = PACKAGE):
    """
    Return the modules of the package under ``root`` that the module ``path`` imports.

    ``from X import name`` counts as an import of ``X.name`` when that is a module of the
    package, else of ``X`` (a name from its ``__init__``); ``import X.Y`` of ``X.Y``. The
    parent packages Python imports on the way are not counted: their ``__init__`` importing a
    child is the usual shape of a package, not a circle.
    """
    parts = [PKG] + list(path.relative_to(root).parent.parts)
    modules = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            modules.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = parts[:len(parts) - node.level + 1]
                module = '.'.join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ''
            for alias in node.names:
                child = f'{module}.{alias.name}'
                modules.add(child if _module_file(child, root) else module)
    own = {module for module in modules if _module_file(module, root)}
    return own - {module_name_under(path, root)}


def _module_file(module: str, root: Path) -> Path | None:
    """Return the file of ``module`` (a module or package under ``root``), else None."""
    parts = module.split('.')
    if parts[0] != PKG:
        return None
    where = root.joinpath(*parts[1:])
    for candidate in (where.with_suffix('.py'), where / '__init__.py'):
        if candidate.is_file():
            return candidate
    return None


def module_name_under(path: Path, root: Path) -> str:
    rel = path.relative_to(root)
    parts = [PKG] + list(rel.parent.parts)
    return '.'.join(parts if path.stem == '__init__' else parts + [path.stem])


def import_circles(root: Path = PACKAGE) -> list[list[str]]:
    """Return every circle of imports under ``root`` (strongly connected modules), sorted."""
    graph = {module_name_under(path, root): module_imports(path, root)
             for path in sorted(root.rglob('*.py'))}
    # Tarjan's strongly connected components, iteratively (no recursion limit to meet).
    index, low, on_stack, stack, circles = {}, {}, set(), [], []
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    circles.append(sorted(component))
    return sorted(circles)


def test_no_import_circle():
    assert import_circles() == []


def _write_package(root: Path, files: dict[str, str]) -> None:
    for rel, source in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(source)


@pytest.mark.parametrize('files, circle', [
    # The circle this check was written for: node -> parameters -> (lazily) docs -> node.
    ({'ros/__init__.py': '',
      'ros/odometry_node.py': 'from tracked_kinematics.ros.parameters import TableNode\n',
      'ros/parameters.py': 'def names():\n'
                           '    from tracked_kinematics.ros.param_docs import NODES\n',
      'ros/param_docs.py': 'from tracked_kinematics.ros import odometry_node\n'},
     ['tracked_kinematics.ros.odometry_node', 'tracked_kinematics.ros.param_docs',
      'tracked_kinematics.ros.parameters']),
    # Relative imports, a name from a package's __init__ that imports the importer.
    ({'params/__init__.py': 'from .tables import TERRAIN\n',
      'params/tables.py': 'from . import spec\n',
      'params/spec.py': 'from tracked_kinematics.params import TERRAIN\n'},
     ['tracked_kinematics.params', 'tracked_kinematics.params.spec',
      'tracked_kinematics.params.tables']),
])
def test_import_circle_check_can_fail(tmp_path, files, circle):
    _write_package(tmp_path, files)
    assert import_circles(tmp_path) == [circle]


def test_import_circle_check_allows_a_package_of_modules(tmp_path):
    # An __init__ importing its children and the children importing each other is no circle.
    _write_package(tmp_path, {
        'params/__init__.py': 'from .tables import TERRAIN\nfrom .spec import check\n',
        'params/tables.py': 'from .spec import check\nimport numpy\n',
        'params/spec.py': 'import math\n',
        'ros/node.py': 'from tracked_kinematics.params import TERRAIN\n'
                       'def later():\n    from tracked_kinematics.params.tables import TERRAIN\n'})
    assert import_circles(tmp_path) == []


# The house's limits (STYLE.md; issue 37 item 9): no function over 80 lines of code but the
# argument parsers (``build_parser``: one add_argument per option, long by nature), no module
# over 700 lines. Lines of code: lines with a token that is neither a comment nor a
# docstring; blank lines do not count. A nested function counts in its own right and in the
# function around it.

MAX_FUNCTION_LINES = 80
MAX_MODULE_LINES = 700
PARSER_FUNCTIONS = {'build_parser'}
# Offenders in files other branches are splitting (issue 37 item 9); each entry goes when its
# split is merged (test_known_offenders_are_still_offenders says when).
KNOWN_LONG_FUNCTIONS: set = set()
KNOWN_LONG_MODULES: set = set()
_NOT_CODE = (tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
             tokenize.ENDMARKER, tokenize.ENCODING)


def code_lines(source: str) -> set:
    """Return the numbers of the lines of ``source`` that hold code (no docstring, comment)."""
    tree = ast.parse(source)
    docstrings = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            first = node.body[0] if node.body else None
            if (isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
                    and isinstance(first.value.value, str)):
                docstrings.update(range(first.lineno, first.end_lineno + 1))
    lines = set()
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type not in _NOT_CODE:
            lines.update(range(token.start[0], token.end[0] + 1))
    return lines - docstrings


def long_functions(source: str, limit: int = MAX_FUNCTION_LINES) -> dict:
    """Return ``{name: lines of code}`` of the functions of ``source`` over ``limit``."""
    lines = code_lines(source)
    found = {}
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) \
                and node.name not in PARSER_FUNCTIONS:
            count = sum(1 for line in lines if node.lineno <= line <= node.end_lineno)
            if count > limit:
                found[node.name] = max(count, found.get(node.name, 0))
    return found


def house_offenders():
    """Return ``({'rel:function': lines}, {'rel': lines})`` over the limits in the package."""
    functions, modules = {}, {}
    for path in sorted(PACKAGE.rglob('*.py')):
        rel = str(path.relative_to(PACKAGE))
        source = path.read_text()
        for name, count in long_functions(source).items():
            functions[f'{rel}:{name}'] = count
        if len(source.splitlines()) > MAX_MODULE_LINES:
            modules[rel] = len(source.splitlines())
    return functions, modules


def test_no_function_over_80_lines_of_code_and_no_module_over_700_lines():
    functions, modules = house_offenders()
    assert {k: v for k, v in functions.items() if k not in KNOWN_LONG_FUNCTIONS} == {}
    assert {k: v for k, v in modules.items() if k not in KNOWN_LONG_MODULES} == {}


def test_known_offenders_are_still_offenders():
    # A split that has landed takes its entry out of the lists above, so that the function
    # cannot grow back unseen.
    functions, modules = house_offenders()
    assert KNOWN_LONG_FUNCTIONS - set(functions) == set()
    assert KNOWN_LONG_MODULES - set(modules) == set()


def test_the_line_count_skips_docstrings_comments_and_blank_lines():
    body = '\n'.join(f'    x{k} = {k}' for k in range(79))
    source = (f'def f():\n    """\n    Doc.\n\n    More.\n    """\n    # note\n\n{body}\n'
              f'def build_parser():\n{body}\n    y = 1\n    z = 2\n')
    # f: its def line and 79 statements, at the limit; build_parser is exempt.
    assert long_functions(source) == {}
    # A statement over two lines counts two; a nested function counts in both.
    longer = source.replace('    # note\n', '    z = [\n        1]\n    def g():\n'
                            '        return 1\n')
    assert long_functions(longer) == {'f': 84}
    assert long_functions(longer, limit=1) == {'f': 84, 'g': 2}


# A node or tool starts as a process of its own, dozens of times in the suite and at every
# `ros2 run`: scipy's optimiser, signal, statistics and interpolation packages take 0.2-0.7 s
# each to import (the nodes' imports were 1.0-1.2 s with them, 0.26-0.31 s without), so core
# imports them inside the functions that use them.
HEAVY = ('scipy.optimize', 'scipy.signal', 'scipy.stats', 'scipy.interpolate',
         'scipy.spatial', 'matplotlib')
STARTED_MODULES = [
    'tracked_kinematics.ros.odometry_node', 'tracked_kinematics.ros.cmd_vel_translator',
    'tracked_kinematics.ros.icr_estimator', 'tracked_kinematics.ros.tracked_simulator',
    'tracked_kinematics.ros.calibration_drive_node', 'tracked_kinematics.offline.cli.identify_icr',
    'tracked_kinematics.offline.cli.evaluate_model']


def heavy_imports(module: str, path: str = '') -> list[str]:
    """Return the packages of :data:`HEAVY` that importing ``module`` loads, in a new process."""
    import subprocess
    import sys
    code = (f'import sys; sys.path.insert(0, {path!r}); import {module}; '
            f'print(" ".join(m for m in {HEAVY!r} if m in sys.modules))')
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          check=True, timeout=120)
    return done.stdout.split()


@pytest.mark.parametrize('module', STARTED_MODULES)
def test_a_node_or_tool_starts_without_the_heavy_scipy_packages(module):
    assert heavy_imports(module) == []


def test_the_heavy_import_check_can_fail(tmp_path):
    (tmp_path / 'eager_node.py').write_text('from scipy import signal\n')
    assert 'scipy.signal' in heavy_imports('eager_node', str(tmp_path))


def test_the_longest_first_files_exist():
    # A renamed file would silently lose its place at the front of the schedule. (Read from
    # the source: test/offline has a conftest of its own.)
    root = PACKAGE.parent
    tree = ast.parse((root / 'test' / 'conftest.py').read_text())
    LONGEST_FIRST = next(ast.literal_eval(node.value) for node in tree.body
                         if isinstance(node, ast.AnnAssign | ast.Assign)
                         and 'LONGEST_FIRST' in ast.unparse(node))
    assert [name for name in LONGEST_FIRST if not (root / name).is_file()] == []
