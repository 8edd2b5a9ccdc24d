"""What setup.py declares, read without running it (for packaging and launch tests)."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def console_scripts():
    """Map of console script name -> 'module:function' declared in setup.py."""
    tree = ast.parse((ROOT / 'setup.py').read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Dict):
            for key, value in zip(node.keys, node.values):
                if isinstance(key, ast.Constant) and key.value == 'console_scripts':
                    entries = [ast.literal_eval(elt) for elt in value.elts]
                    return dict(tuple(part.strip() for part in entry.split('=', 1))
                                for entry in entries)
    raise AssertionError('setup.py declares no console_scripts')
