"""
The parameter reference, docs/parameters.md, generated from the parameter tables.

The shared tables of :mod:`.tables` and the nodes' of :mod:`.node_tables`. Regenerate with
``python -m tracked_kinematics.params.param_docs`` (``--check``: exit 1 when stale).
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable, Sequence
from pathlib import Path
import sys

from .node_tables import NODE_PARAMS
from .spec import ParamSpec
from .tables import COMMAND_LIMIT_PARAMS, DRIVETRAIN_PARAMS, ENCODER_INPUT_PARAMS, TERRAIN_PARAMS

ROOT = Path(__file__).resolve().parents[2]
OUTPUT = ROOT / 'docs' / 'parameters.md'
COMMAND = 'python -m tracked_kinematics.params.param_docs'

# The shared tables: (anchor heading, table name, table, what it is, checked together).
SHARED = (
    ('Terrain', 'TERRAIN_PARAMS', TERRAIN_PARAMS,
     'The kinematic model of one vehicle on one terrain: what a terrain file holds and '
     '`identify_icr` writes ([model](model.md)). There is no default vehicle: '
     '`track_width` and `sprocket_radius` must be given; the ICRs default to the ideal '
     'differential drive of that width.',
     'Checked together (`params.icr_from_values`): `icr.y_left > icr.y_right`, and the '
     'steering efficiency chi = `track_width / (icr.y_left - icr.y_right)` in (0, 1], i.e. '
     'the tread ICRs at least `track_width` apart.'),
    ('Drive train', 'DRIVETRAIN_PARAMS', DRIVETRAIN_PARAMS,
     'How the tracks follow their setpoints (Fink & Stump sec. III-B; '
     '[simulator](simulator.md#drive-train)). Optional in a terrain '
     'file, written by [`identify_drivetrain`](tools/identify_drivetrain.md); vehicle files '
     'use the same keys.',
     'Checked together (`params.drivetrain_from_values`): with `pid_dc_motor`, at least one '
     'of the gains > 0 and a stable closed speed loop.'),
    ('Encoder input', 'ENCODER_INPUT_PARAMS', ENCODER_INPUT_PARAMS,
     'Which encoder messages a node subscribes to '
     '([input modes](nodes/odometry_node.md#encoder-input)); the '
     'offline tools take the same choices as `--encoder-input` and flags.',
     'Checked together: no joint in both `left_joints` and `right_joints`.'),
    ('Command limits', 'COMMAND_LIMIT_PARAMS', COMMAND_LIMIT_PARAMS,
     'Limits of [`cmd_vel_translator`]'
     '(nodes/cmd_vel_translator.md#limits-and-the-vehicle-envelope), which '
     "`plan_trajectory` also reads from a terrain file. The names are diff_drive_controller's; "
     'a velocity limit scales `v_x` and `w` together, so the commanded curvature is kept.',
     ''),
)

# What each node of :data:`~.node_tables.NODE_PARAMS` checks together, in words.
TOGETHER = {
    'odometry_node':
    'Checked together: the terrain and encoder checks above, and `odom_frame` != '
    '`base_frame`.',
    'cmd_vel_translator': 'Checked together: the terrain checks above.',
    'icr_estimator':
    'Checked together: the terrain, drive-train and encoder checks above, and '
    '`min_window <= window < max_window`.',
    'tracked_simulator':
    'Checked together: the vehicle file loads (every problem of it named) and `terrain` is '
    "one of the shipped terrains or the vehicle file's own `friction.terrain`.",
    'calibration_drive':
    'Checked together: the terrain and encoder checks above, and a deadman '
    '(`deadman_topic` or `joy_topic`). `output`, the report beside it and `bag` are checked '
    'as files at start ([output files](output-files.md)).',
}

# The nodes: (name, the table it declares, checked together).
NODES = tuple((node, specs, TOGETHER[node]) for node, specs in NODE_PARAMS.items())

_TYPES = ((bool, 'bool'), (int, 'integer'), (float, 'double'), (str, 'string'),
          (list, 'string array'))


def _type(spec: ParamSpec) -> str:
    for python_type, ros_type in _TYPES:
        if isinstance(spec.default, python_type):
            return ros_type
    raise TypeError(f'{spec.name}: no ROS parameter type for default {spec.default!r}')


def _default(value) -> str:
    if isinstance(value, bool):
        text = 'true' if value else 'false'
    elif isinstance(value, float):
        text = repr(value)
    elif isinstance(value, list):
        text = '[' + ', '.join(value) + ']'
    elif isinstance(value, str):
        text = value or "''"
    else:
        text = str(value)
    return f'`{text}`'


def _check(spec: ParamSpec) -> str:
    """Return the check in words; a check without words is an error (it would go undocumented)."""
    parts = []
    if spec.check is not None:
        words = getattr(spec.check, 'words', None)
        if not words:
            raise ValueError(
                f'{spec.name}: its check {spec.check.__qualname__} has no words; decorate it '
                'with tracked_kinematics.params.described_as')
        parts.append(words)
    if spec.has_range:
        low = '' if spec.low is None else f'{spec.low:g}'
        high = '' if spec.high is None else f'{spec.high:g}'
        parts.append(f'in [{low or "-inf"}, {high or "inf"}]')
    if spec.read_only:
        parts.append('read-only')
    return '; '.join(parts)


def _cell(text: str) -> str:
    return text.replace('|', '\\|')


def table(specs: Iterable[ParamSpec]) -> list[str]:
    """Return the Markdown table of ``specs``, one row per parameter."""
    lines = ['| name | type | default | unit | range / check | description |',
             '|---|---|---|---|---|---|']
    for spec in specs:
        default = ('**required**' if spec.required else spec.derived.text
                   if spec.derived is not None else _default(spec.default))
        cells = (f'`{spec.name}`', _type(spec), default, spec.unit,
                 _check(spec), spec.description)
        lines.append('| ' + ' | '.join(_cell(cell) for cell in cells) + ' |')
    return lines


def _split(specs: Sequence[ParamSpec]) -> tuple[list[str], list[ParamSpec]]:
    """Shared tables a node declares in full, and the parameters of its own."""
    names = [spec.name for spec in specs]
    if len(set(names)) != len(names):
        raise ValueError(f'a parameter is declared twice: {names}')
    shared, covered = [], set()
    for heading, _, shared_specs, _, _ in SHARED:
        if all(spec in specs for spec in shared_specs):
            shared.append(heading)
            covered.update(spec.name for spec in shared_specs)
    return shared, [spec for spec in specs if spec.name not in covered]


def _anchor(heading: str) -> str:
    return heading.lower().replace(' ', '-')


def parameters_markdown() -> str:
    """
    Return docs/parameters.md: every parameter table, shared and per node.

    ValueError when a check has no words (:func:`~tracked_kinematics.params.described_as`) or a
    node declares a name twice.
    """
    out = [
        '# Parameter reference',
        '',
        f'<!-- Generated by `{COMMAND}` from the parameter tables; do not edit by hand. -->',
        '',
        'Every parameter of the nodes, generated from the tables they declare '
        '(`tracked_kinematics/params/tables.py` and, per node, '
        '`tracked_kinematics/params/node_tables.py`); `ros2 param describe NODE NAME` shows '
        'the same description and unit. Give them in a YAML file with '
        '`--ros-args --params-file FILE` (several files: the last one wins per parameter) or '
        'one by one with `-p NAME:=VALUE`. `track_width` and `sprocket_radius` given twice '
        '(two files, a file and a `-p`) must agree within rounding (0.5 % or 0.5 mm: '
        '`params.dimensions`), else the node refuses to start, naming both sources: the '
        'terrain file of another robot.',
        '',
        '- **type**: the ROS parameter type; a `double` also accepts an integer.',
        '- **range / check**: checked at start (an invalid value gives one `FATAL` line naming '
        'it, exit status 2) and on every runtime change (`ros2 param set` is refused with the '
        'reason; the node keeps its old values). **read-only**: fixed at start.',
        '- Valid runtime changes apply from the next message or setpoint.',
        '',
        f'Regenerate after changing a table: `{COMMAND}` (test/package/test_docs.py fails '
        'while this page is stale).',
        '',
        '## Shared tables',
        '',
        'Declared by several nodes; a node that declares a table declares all of it.',
    ]
    for heading, name, specs, about, together in SHARED:
        out += ['', f'### {heading}', '', f'`tracked_kinematics.params.{name}`. {about}', '']
        out += table(specs)
        if together:
            out += ['', together]
    out += ['', '## Nodes']
    for node, specs, together in NODES:
        shared, own = _split(specs)
        listed = ', '.join(f'[{heading.lower()}](#{_anchor(heading)})' for heading in shared)
        declares = (f'Declares the shared tables {listed}, and its own:' if shared
                    else 'Its parameters:')
        out += ['', f'### {node}', '', f'Page: [{node}](nodes/{node}.md). {declares}', '']
        out += table(own)
        out += ['', together]
    return '\n'.join(out) + '\n'


def main(argv: Sequence[str] | None = None) -> int:
    """Write docs/parameters.md, or with ``--check`` report whether it is current."""
    parser = argparse.ArgumentParser(
        prog=COMMAND, description='Generate docs/parameters.md from the parameter tables.')
    parser.add_argument('--output', type=Path, default=OUTPUT,
                        help='file to write (default: docs/parameters.md of the source tree)')
    parser.add_argument('--check', action='store_true',
                        help='write nothing; exit 1 when the file is not what would be written')
    args = parser.parse_args(argv)
    text = parameters_markdown()
    if args.check:
        current = args.output.read_text() if args.output.is_file() else None
        if current != text:
            print(f'{args.output} is stale: regenerate with `{COMMAND}`', file=sys.stderr)
            return 1
        return 0
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text)
    print(f'wrote {args.output}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
