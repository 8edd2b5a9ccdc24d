"""The docs: the generated parameter reference is current, links resolve, examples are valid."""

import contextlib
import importlib
import io
import re
import shlex

from helpers.setup_info import console_scripts, ROOT
import pytest
from tracked_kinematics.params.node_tables import NODE_PARAMS

README = ROOT / 'README.md'
DOCS = ROOT / 'docs'
REGENERATE = '.venv/bin/python -m tracked_kinematics.params.param_docs'
MAX_README_LINES = 250

FENCE = re.compile(r'^(```|~~~).*?^\1[^\n]*$', re.S | re.M)
CODE_SPAN = re.compile(r'`[^`\n]*`')
INDENTED = re.compile(r'^(?: {4}|\t).*$', re.M)
LINK = re.compile(r'!?\[[^\]\n]*\]\(\s*<?([^)\s>]+)>?(?:\s+"[^"]*")?\s*\)')
HEADING = re.compile(r'^#{1,6}\s+(.*?)\s*#*\s*$', re.M)
FENCED = re.compile(r'^```(\w*)\n(.*?)^```', re.S | re.M)
# Every parameter each node declares, by node (console script) name.
NODE_TABLES = NODE_PARAMS


def markdown_files():
    return [README] + sorted(DOCS.rglob('*.md'))


def _prose(text):
    """Return the text without code blocks and code spans, where brackets are not links."""
    return CODE_SPAN.sub('', INDENTED.sub('', FENCE.sub('', text)))


def anchors(path):
    """Return the heading anchors of a Markdown file as GitHub makes them."""
    seen = {}
    result = set()
    for heading in HEADING.findall(FENCE.sub('', path.read_text())):
        slug = re.sub(r'[^\w\- ]', '', heading.strip().lower()).replace(' ', '-')
        count = seen.get(slug, 0)
        seen[slug] = count + 1
        result.add(slug if count == 0 else f'{slug}-{count}')
    return result


def broken_links(path):
    """Return the relative links of ``path`` whose file (or heading anchor) does not exist."""
    broken = []
    for target in LINK.findall(_prose(path.read_text())):
        if re.match(r'^[a-z][a-z0-9+.-]*:', target, re.I):   # http:, https:, mailto:
            continue
        file_part, _, anchor = target.partition('#')
        linked = (path.parent / file_part).resolve() if file_part else path
        if not linked.exists():
            broken.append(f'{target} (no file {linked})')
        elif anchor and linked.suffix == '.md' and anchor not in anchors(linked):
            broken.append(f'{target} (no heading #{anchor} in {linked.name})')
    return broken


def test_parameters_md_is_current():
    from tracked_kinematics.params.param_docs import parameters_markdown
    path = DOCS / 'parameters.md'
    assert path.is_file(), f'docs/parameters.md is missing: generate it with `{REGENERATE}`'
    assert path.read_text() == parameters_markdown(), (
        f'docs/parameters.md is stale (a parameter table changed): regenerate it with '
        f'`{REGENERATE}` and commit the result')


def test_parameters_md_lists_every_parameter_of_every_node():
    from tracked_kinematics.ros import (calibration_drive_node, cmd_vel_translator, icr_estimator,
                                        odometry_node, tracked_simulator)
    text = (DOCS / 'parameters.md').read_text()
    # What the nodes declare, read from the node modules: the tables they use are documented.
    for table in (odometry_node.PARAMS, cmd_vel_translator.TRANSLATOR_PARAMS,
                  icr_estimator.PARAMS, calibration_drive_node.PARAMS,
                  tracked_simulator.SIMULATOR_PARAMS):
        for spec in table:
            assert f'| `{spec.name}` |' in text, spec.name


def test_a_check_without_words_is_refused():
    # The generator must not document a check it cannot describe.
    from tracked_kinematics.params import ParamSpec
    from tracked_kinematics.params.param_docs import table
    spec = ParamSpec('made_up', 1.0, 'Made up', 'm', check=lambda value: None)
    with pytest.raises(ValueError, match='made_up'):
        table([spec])


@pytest.mark.parametrize('path', markdown_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(path):
    assert not broken_links(path), f'{path.relative_to(ROOT)}: broken links {broken_links(path)}'


def test_link_checker_flags_a_broken_link(tmp_path):
    # The test above must be able to fail.
    (tmp_path / 'there.md').write_text('# A heading: with `code`\n')
    page = tmp_path / 'page.md'
    page.write_text('[ok](there.md) [ok too](there.md#a-heading-with-code) [web](https://x.org)\n'
                    '[gone](made_up/nowhere.md) [bad anchor](there.md#no-such-heading)\n'
                    '`[not a link](in_code.md)`\n\n```\n[nor](in_a_block.md)\n```\n')
    found = broken_links(page)
    assert len(found) == 2, found
    assert found[0].startswith('made_up/nowhere.md')
    assert found[1].startswith('there.md#no-such-heading')


def test_every_executable_has_its_page():
    pages = {p.stem for p in (DOCS / 'nodes').glob('*.md')} | {
        p.stem for p in (DOCS / 'tools').glob('*.md')}
    missing = sorted(set(console_scripts()) - pages)
    assert not missing, f'console scripts without a page in docs/nodes or docs/tools: {missing}'


def test_readme_is_a_front_door():
    lines = README.read_text().splitlines()
    assert len(lines) <= MAX_README_LINES, (
        f'README.md has {len(lines)} lines; keep it <= {MAX_README_LINES} and move detail '
        'to docs/')


def example_commands(path):
    """Return the command lines of a page: bash blocks, and ``$ `` lines of output blocks."""
    commands = []
    for language, body in FENCED.findall(path.read_text()):
        if language not in ('', 'bash'):
            continue
        lines = body.replace('\\\n', ' ').splitlines()
        for line in lines:
            if line.lstrip().startswith('$ '):
                line = line.lstrip()[2:]
            elif language != 'bash':
                continue
            words = shlex.split(line, comments=True)
            if words:
                commands.append(words)
    return commands


def synopses(path):
    """Return (script, options) of each indented usage block (``identify_icr BAG ...``)."""
    scripts = console_scripts()
    found = []
    for block in re.findall(r'(?:^(?: {4}).*\n?)+', FENCE.sub('', path.read_text()), re.M):
        first = block.split()[0]
        if first in scripts and first not in NODE_TABLES:
            found.append((first, sorted(set(re.findall(r'(?<![\w-])--?[a-z][\w-]*', block)))))
    return found


def _parser(script):
    module = importlib.import_module(console_scripts()[script].split(':')[0])
    return module.build_parser()


@pytest.mark.parametrize('path', markdown_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_usage_blocks_name_real_options(path):
    problems = []
    for script, options in synopses(path):
        known = set(_parser(script)._option_string_actions)
        problems += [f'{script} has no option {option}' for option in options
                     if option not in known]
    assert not problems, problems


def check_command(words):
    """Return what is wrong with one documented command line of the package, or None."""
    scripts = console_scripts()
    if words[:2] == ['ros2', 'run']:
        if words[2] != 'tracked_kinematics':
            return None
        if words[3] not in scripts:
            return f'no console script {words[3]}'
        if words[3] not in NODE_TABLES:
            return None
        declared = {spec.name for spec in NODE_TABLES[words[3]]}
        declared.add('use_sim_time')  # every rclpy node declares it
        names = [words[i + 1].split(':=')[0] for i, word in enumerate(words[:-1])
                 if word == '-p']
        unknown = [name for name in names if name not in declared]
        return f'{words[3]} declares no parameter {unknown}' if unknown else None
    if words[:2] == ['ros2', 'launch']:
        return None if (ROOT / 'launch' / words[3]).is_file() else f'no launch file {words[3]}'
    if words[0] not in scripts or words[0] in NODE_TABLES:
        return None
    stderr = io.StringIO()
    try:
        with contextlib.redirect_stderr(stderr):
            _parser(words[0]).parse_args(words[1:])
    except SystemExit:
        return stderr.getvalue().strip().splitlines()[-1]
    return None


@pytest.mark.parametrize('path', markdown_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_documented_commands_are_valid(path):
    # Console-script examples parse with the script's own parser; ros2 run names a console
    # script and only parameters its node declares; ros2 launch names a shipped file.
    problems = [f'{" ".join(words)}: {problem}' for words in example_commands(path)
                for problem in [check_command(words)] if problem]
    assert not problems, '\n'.join(problems)


def test_command_checker_flags_a_wrong_flag(tmp_path):
    page = tmp_path / 'page.md'
    page.write_text('```bash\nicr_map auriga_alpha --no-such-flag\n'
                    'ros2 run tracked_kinematics odometry_node --ros-args -p made_up:=1\n'
                    'simulate_bag run1 --vehicle packbot \\\n    --seed 1   # fine\n```\n')
    problems = [check_command(words) for words in example_commands(page)]
    assert 'unrecognized arguments: --no-such-flag' in problems[0]
    assert 'made_up' in problems[1]
    assert problems[2] is None
    page.write_text('Usage:\n\n    icr_map [VEHICLE] [--n 21]\n        [--made-up-flag X]\n')
    assert synopses(page) == [('icr_map', ['--made-up-flag', '--n'])]


def _node_specs():
    return {node: {spec.name: spec for spec in specs} for node, specs in NODE_PARAMS.items()}


def _stated_default_problem(spec, cell):
    """Say how a page's default cell differs from the spec's, or return None."""
    import yaml
    text = cell.replace('**', '').replace('`', '').strip()
    if spec.unit and text.endswith(' ' + spec.unit):
        text = text[:-len(spec.unit) - 1]
    if spec.required:
        return None if text == 'required' else f'stated {cell!r}, the table: required'
    if spec.derived is not None:
        return None if text == spec.derived.text else \
            f'stated {cell!r}, the table: {spec.derived.text}'
    try:
        value = float(text)
    except ValueError:
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError:
            value = text
    if isinstance(spec.default, list) and isinstance(value, list):
        value = [str(v) for v in value]
    if value == spec.default or (value in (None, '') and spec.default == ''):
        return None
    return f'stated {cell!r}, the table: {spec.default!r}'


RANGE = re.compile(r'\[\s*([^,\]\s]+)\s*,\s*([^\]\s]+)\s*\]')


def _stated_range_problem(spec, text):
    match = RANGE.search(text)
    if not match:
        return None
    stated = [float(v) for v in match.groups()]
    have = [-float('inf') if spec.low is None else float(spec.low),
            float('inf') if spec.high is None else float(spec.high)]
    return None if stated == have else \
        f'stated range {match.group(0)}, the table: [{spec.low:g}, {spec.high:g}]'


def stated_parameter_problems(path, specs):
    """Defaults and ranges a node page states in its tables that its parameter table has not."""
    problems = []
    columns = None
    for line in path.read_text().splitlines():
        if not line.startswith('|'):
            columns = None
            continue
        cells = [cell.strip() for cell in line.strip().strip('|').split('|')]
        if columns is None:
            columns = [cell.lower() for cell in cells]
            continue
        if set(line) <= set('|-: ') or 'default' not in columns:
            continue
        name = re.fullmatch(r'`([A-Za-z_.]+)`', cells[0])
        if not name or name.group(1) not in specs or len(cells) != len(columns):
            continue
        spec = specs[name.group(1)]
        problem = _stated_default_problem(spec, cells[columns.index('default')])
        if problem is None and 'range' in columns:
            problem = _stated_range_problem(spec, cells[columns.index('range')])
        if problem:
            problems.append(f'{path.name}: {spec.name}: {problem}')
    prose = path.read_text()
    for match in re.finditer(r'`([a-z_.]+)`\s+(\[[^\]\n]+\])', prose):
        spec = specs.get(match.group(1))
        if spec is not None and spec.has_range:
            problem = _stated_range_problem(spec, match.group(2))
            if problem:
                problems.append(f'{path.name}: {spec.name}: {problem}')
    return problems


@pytest.mark.parametrize('node', sorted(NODE_TABLES))
def test_node_pages_state_the_tables_defaults_and_ranges(node):
    # Issue 31: docs/parameters.md showed 0.42 / 0.1 for the required track_width and
    # sprocket_radius; the pages gave sprocket_radius three different ranges.
    assert stated_parameter_problems(DOCS / 'nodes' / f'{node}.md', _node_specs()[node]) == []


def test_generated_reference_states_no_default_for_a_required_parameter():
    text = (DOCS / 'parameters.md').read_text()
    for name in ('track_width', 'sprocket_radius'):
        row = next(line for line in text.splitlines() if line.startswith(f'| `{name}` |'))
        assert row.split('|')[3].strip() == '**required**', row
    row = next(line for line in text.splitlines() if line.startswith('| `icr.y_left` |'))
    assert row.split('|')[3].strip() == '+track_width / 2', row


def test_the_docs_check_flags_a_wrong_default_and_range(tmp_path):
    from tracked_kinematics.params import TERRAIN_PARAMS
    page = tmp_path / 'probe.md'
    page.write_text('| parameter | default | range |\n|---|---|---|\n'
                    '| `track_width` | `0.42` | [0.01, 20] |\n'
                    '| `icr.x` | `0` | [-1, 1] |\n| `scale.left` | `1` | [0.1, 10] |\n\n'
                    'The radius `sprocket_radius` [1e-05, 10] m.\n')
    problems = stated_parameter_problems(page, {s.name: s for s in TERRAIN_PARAMS})
    assert [p.split(':')[1].strip() for p in problems] == ['track_width', 'icr.x',
                                                           'sprocket_radius']


def test_the_demo_figure_check_can_fail():
    from helpers.demo_page import differences
    line = '   mean                  22.3       60     6.579       87.3    28.3     0.860'
    assert not differences(line, line.replace('0.860', '0.861'))      # the last digit
    assert differences(line, line.replace('0.860', '0.870'))
    assert differences(line, line.replace('mean', 'median'))
    assert differences(line + '\nmore', line)
