"""Read and write ROS 2 parameter files (``/**: ros__parameters:``) as dotted names."""

from __future__ import annotations

from collections.abc import Mapping
import os
import stat
import tempfile
from typing import Any

from tracked_kinematics.core.errors import InvalidParameters
import yaml


def flatten(tree: Mapping[str, Any], prefix: str = '') -> dict[str, Any]:
    """Nested mapping -> dotted names (``{'icr': {'x': 1}} -> {'icr.x': 1}``)."""
    flat = {}
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, Mapping):
            flat.update(flatten(value, name + '.'))
        else:
            flat[name] = value
    return flat


def nest(flat: Mapping[str, Any]) -> dict[str, Any]:
    """Dotted names -> nested mapping; inverse of :func:`flatten`."""
    tree: dict[str, Any] = {}
    for name, value in flat.items():
        node = tree
        *parents, leaf = name.split('.')
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    return tree


def read_params_file(path: str | os.PathLike, node_name: str | None = None) -> dict[str, Any]:
    """
    Return the parameters of a ROS 2 params file, flattened to dotted names.

    Reads the ``/**`` section and, with ``node_name``, that node's section on top, as
    ``--params-file`` would; a plain mapping without ``ros__parameters`` is read as is.
    Raises :class:`InvalidParameters` when the file is not UTF-8 or not a mapping.
    """
    if not stat.S_ISREG(os.stat(path).st_mode) and not os.path.isdir(path):
        # A FIFO or a device would block or stream forever; a directory raises below.
        raise InvalidParameters(f'{path}: not a regular file')
    with open(path, encoding='utf-8') as stream:
        try:
            doc = yaml.safe_load(stream)
        except yaml.YAMLError as err:
            raise InvalidParameters(f'{path}: not valid YAML ({err})') from None
        except UnicodeDecodeError as err:
            raise InvalidParameters(str(err)) from None
    if not isinstance(doc, Mapping):
        raise InvalidParameters(f'{path}: expected a mapping of parameters')
    sections = [section for section in doc.values()
                if isinstance(section, Mapping) and 'ros__parameters' in section]
    if not sections:
        return flatten(doc)
    flat: dict[str, Any] = {}
    for key, section in doc.items():
        if not isinstance(section, Mapping) or 'ros__parameters' not in section:
            continue
        if key in ('/**', '**') or (node_name is not None
                                    and key.lstrip('/').split('/')[-1] == node_name):
            flat.update(flatten(section['ros__parameters'] or {}))
    return flat


def params_text(values: Mapping[str, Any], comment: str | None = None) -> str:
    """Return dotted ``values`` as a ``/**: ros__parameters:`` file's text, ``comment`` on top."""
    text = yaml.safe_dump({'/**': {'ros__parameters': nest(values)}}, sort_keys=False,
                          default_flow_style=False)
    if comment:
        text = ''.join(f'# {line}\n' for line in comment.splitlines()) + text
    return text


def write_params_file(path: str | os.PathLike, values: Mapping[str, Any],
                      comment: str | None = None) -> None:
    """
    Write dotted ``values`` as a ``/**: ros__parameters:`` file, atomically (temporary + rename).

    The offline tools write through ``offline.outputs.Outputs`` instead (no ``--force``, no links).
    """
    text = params_text(values, comment)
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix='.tmp-', suffix='.yaml', dir=directory)
    try:
        with os.fdopen(fd, 'w', encoding='utf-8') as stream:
            stream.write(text)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
