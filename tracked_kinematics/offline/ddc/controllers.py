"""
Reading a ros2_control controllers file and finding its diff_drive_controller section.

As rcl reads it (no anchors or aliases), in every section form (``<name>: ros__parameters:``,
wildcards, nested namespaces, plain).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
import os
from typing import Any

from tracked_kinematics.offline.errors import DdcError
from tracked_kinematics.params import flatten
import yaml

DDC_TYPE = 'diff_drive_controller/DiffDriveController'

# Keys that mark a mapping as a DDC section when no controller_manager names its type.
_MARKERS = ('wheel_separation', 'left_wheel_names', 'right_wheel_names')


class _NoAliasLoader(yaml.SafeLoader):
    """Safe loader that refuses anchors and aliases, as rcl does (recursive aliases)."""

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise DdcError(f'line {event.start_mark.line + 1}: YAML alias *{event.anchor}: '
                           'ROS 2 parameter files cannot use anchors and aliases (rcl refuses '
                           'them)')
        return super().compose_node(parent, index)


def load_controllers(path: str | os.PathLike) -> Any:
    """Read a controllers YAML file; DdcError naming it when unreadable or no mapping."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise DdcError(f'{path}: no such file')
    if not os.path.isfile(path):
        raise DdcError(f'{path}: not a regular file')
    try:
        with open(path, encoding='utf-8') as stream:
            doc = yaml.load(stream, Loader=_NoAliasLoader)  # noqa: S506 -- a SafeLoader
    except DdcError as err:
        raise DdcError(f'{path}: {err}') from None
    except RecursionError:
        raise DdcError(f'{path}: nested too deeply to be a parameter file') from None
    except OSError as err:
        raise DdcError(f'{path}: cannot be read: {err.strerror}') from None
    except UnicodeDecodeError:
        raise DdcError(f'{path}: not a text (UTF-8) file') from None
    except yaml.YAMLError as err:
        raise DdcError(f'{path}: not valid YAML: {" ".join(str(err).split())}') from None
    if not isinstance(doc, Mapping):
        raise DdcError(f'{path}: not a YAML mapping of controllers (got '
                       f'{"an empty file" if doc is None else type(doc).__name__})')
    return doc


def _normal_name(path: list) -> tuple[str, bool]:
    """Map a section key path to ``(node name, applies in any namespace)``: ``['/**', 'ddc']``."""
    name = '/'.join(str(part).strip('/') for part in path if str(part).strip('/'))
    wildcard = '*' in name
    while name.startswith('**/') or name.startswith('*/'):
        name = name.split('/', 1)[1]
    return name or '/**', wildcard


def _leaf(name: str) -> str:
    return name.rstrip('/').split('/')[-1]


def _has_markers(params: Mapping) -> bool:
    return any(key in params for key in _MARKERS)


def _raw_sections(doc: Mapping) -> list[tuple[str, bool, Mapping]]:
    """``(node name, any namespace, parameters)`` of every section, in file order."""
    found: list[tuple[str, bool, Mapping]] = []

    def walk(node: Mapping, path: list) -> None:
        for key, value in node.items():
            if key == 'ros__parameters':
                found.append((*_normal_name(path), value if isinstance(value, Mapping) else {}))
            elif isinstance(value, Mapping):
                walk(value, path + [key])

    walk(doc, [])
    if found:
        return found

    # No ros__parameters anywhere: plain forms, sections found by their DDC keys.
    def walk_plain(node: Mapping, path: list) -> None:
        if _has_markers(node):
            name, wildcard = _normal_name(path) if path else ('(top level)', False)
            found.append((name, wildcard, node))
            return
        for key, value in node.items():
            if isinstance(value, Mapping):
                walk_plain(value, path + [key])

    walk_plain(doc, [])
    return found


def _declared_types(doc: Mapping) -> dict[str, str]:
    """Map controller names (leaf) to types, from every ``<name>: {type: ...}`` in the file."""
    types: dict[str, str] = {}

    def walk(node: Mapping, parent) -> None:
        for key, value in node.items():
            if not isinstance(value, Mapping):
                continue
            kind = value.get('type')
            if isinstance(kind, str):
                owner = parent if key == 'ros__parameters' else key
                if owner is not None:
                    types[_leaf(str(owner))] = kind
            walk(value, key)

    walk(doc, None)
    return types


@dataclass
class Section:
    """
    The DDC section of a controllers file.

    ``name`` with its namespace if given (``a200/platform_controller``); ``params`` as dotted
    names, sections of one node merged in file order as rcl does; ``found_by`` for the report;
    ``any_namespace`` when given for any namespace (``/**/name`` or under ``/**:``).
    """

    name: str
    params: dict[str, Any]
    found_by: str
    any_namespace: bool = False

    @property
    def namespace(self) -> str | None:
        """Return the node's namespace without slashes ('' = root), None when any applies."""
        return None if self.any_namespace else self.name.rpartition('/')[0]


def find_controller(doc: Mapping, controller: str | None = None, source: str = '') -> Section:
    """
    Find the DDC section of a controllers file: ``controller``, or the one of DDC type or keys.

    DdcError for no section, several without ``controller``, or a ``controller`` not found or of
    another type.
    """
    where = f'{source}: ' if source else ''
    groups: dict[str, dict[str, Any]] = {}
    wildcard: dict[str, bool] = {}
    for name, any_ns, params in _raw_sections(doc):
        groups.setdefault(name, {}).update(flatten(params))
        wildcard[name] = wildcard.get(name, False) or any_ns
    types = _declared_types(doc)

    def type_of(name: str) -> str | None:
        own = groups[name].get('type')
        return own if isinstance(own, str) else types.get(_leaf(name))

    def section(name: str, found_by: str) -> Section:
        return Section(name, groups[name], found_by, wildcard[name])

    if controller is not None:
        wanted = _normal_name([controller])[0]
        matches = [n for n in groups if n == wanted] or [
            n for n in groups if _leaf(n) == _leaf(wanted)]
        if not matches:
            listed = ', '.join(groups) or 'none'
            raise DdcError(f'{where}no section for controller {controller!r} (sections: '
                           f'{listed})')
        if len(matches) > 1:
            raise DdcError(f'{where}--controller {controller!r} matches several sections '
                           f'({", ".join(matches)}); give the namespace too')
        name = matches[0]
        kind = type_of(name)
        if kind is not None and kind != DDC_TYPE:
            raise DdcError(f'{where}controller {name!r} is a {kind}, not a {DDC_TYPE}')
        return section(name, 'named by --controller')

    declared = [n for n in groups if type_of(n) == DDC_TYPE]
    by_keys = [n for n in groups if type_of(n) is None and _has_markers(groups[n])]
    candidates = declared + by_keys
    if not candidates:
        orphans = sorted(k for k, v in types.items() if v == DDC_TYPE)
        if orphans:
            raise DdcError(
                f'{where}{", ".join(map(repr, orphans))} is declared as {DDC_TYPE} but the '
                f'file has no section with its parameters')
        raise DdcError(
            f'{where}no diff_drive_controller section (no controller of type {DDC_TYPE} and no '
            f'section with {", ".join(_MARKERS)})')
    if len(candidates) > 1:
        raise DdcError(f'{where}{len(candidates)} diff_drive_controller sections '
                       f'({", ".join(candidates)}): choose one with --controller NAME')
    name = candidates[0]
    if name in declared:
        return section(name, f'its type is {DDC_TYPE}')
    return section(name, 'found by its diff_drive_controller keys')
