"""The result of converting a DDC section: our values, the parameter file and the report."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from tracked_kinematics.params import nest
import yaml

AXES = ('linear.x', 'angular.z')

# Every key goes to every node (``/**``): the vehicle, the joints, the frames, the limits mean
# the same to every node that declares them, so one file serves odometry_node,
# cmd_vel_translator, icr_estimator and calibration_drive alike, and ``-p`` on the command
# line still overrides it (rcl gives a section naming the node precedence over ``-p``).
# Only a key that another node of the package declares with another meaning goes to its
# node's section: icr_estimator's publish_rate is the rate of its estimates.
TERRAIN_KEYS = ('track_width', 'sprocket_radius', 'icr.y_left', 'icr.y_right', 'icr.x',
                'scale.left', 'scale.right')
NODE_KEYS = {'odometry_node': ('publish_rate',)}


class _NoAliasDumper(yaml.SafeDumper):
    """Safe dumper that writes a shared list twice: rcl's YAML parser refuses aliases."""

    def ignore_aliases(self, data) -> bool:
        return True


@dataclass
class Conversion:
    """
    The result of converting one DDC section.

    Attributes
    ----------
    values : dict
        Our parameter names (dotted) to values.
    mapped : list of (str, str)
        ``(DDC side, our side)`` texts, one per mapping.
    not_mapped : list of (str, str)
        ``(DDC key = value, reason)`` for every key without a counterpart.
    warnings : list of str
        Where the converted robot differs from DDC's, or DDC's file is suspicious.
    narrowed : bool
        ``wheel_separation_multiplier < 1``: ``track_width`` is DDC's effective separation.

    """

    controller: str
    found_by: str = ''
    values: dict[str, Any] = field(default_factory=dict)
    mapped: list[tuple[str, str]] = field(default_factory=list)
    not_mapped: list[tuple[str, str]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    narrowed: bool = False

    def sections(self) -> dict[str, dict[str, Any]]:
        """Parameter file sections: ``/**`` for all but :data:`NODE_KEYS`, ``/**/<node>``."""
        own = {key for keys in NODE_KEYS.values() for key in keys}
        out = {'/**': {k: v for k, v in self.values.items() if k not in own}}
        for node, keys in NODE_KEYS.items():
            values = {k: self.values[k] for k in keys if k in self.values}
            if values:
                out[f'/**/{node}'] = values
        return out

    def yaml_text(self, source: str = '') -> str:
        """Return the parameter file: a comment saying where it came from, then the sections."""
        y_left, y_right = self.values['icr.y_left'], self.values['icr.y_right']
        chi = self.values['track_width'] / (y_left - y_right)
        header = [
            'Converted by convert_diff_drive_params from the diff_drive_controller section',
            f'{self.controller!r}' + (f' of {source}' if source else '') + '.',
            f"DDC's kinematics as a tread model: chi = {chi:.4f}, e = 0"
            + (' (track_width is the effective separation, see the warning)'
               if self.narrowed else '') + '.',
            'Load it into every node of tracked_kinematics with --ros-args --params-file:',
            '/** is for every node; /**/<node> holds what another node reads otherwise.',
        ]
        doc = {key: {'ros__parameters': nest(values)} for key, values in self.sections().items()}
        text = yaml.dump(doc, Dumper=_NoAliasDumper, sort_keys=False, default_flow_style=False)
        return ''.join(f'# {line}\n' for line in header) + text


def report_lines(conv: Conversion, width: int = 46) -> list[str]:
    """Return the report of a conversion: what was mapped, what not and why."""
    lines = [f'diff_drive_controller section {conv.controller!r} ({conv.found_by})', '',
             'mapped (diff_drive_controller -> tracked_kinematics):']
    for ddc, ours in conv.mapped:
        if len(ddc) < width:
            lines.append(f'  {ddc.ljust(width)}-> {ours}')
        else:
            lines += [f'  {ddc}', f'  {"":{width}}-> {ours}']
    lines += ['', 'not mapped:']
    lines += [f'  {ddc}: {reason}' for ddc, reason in conv.not_mapped] or ['  (nothing)']
    return lines
