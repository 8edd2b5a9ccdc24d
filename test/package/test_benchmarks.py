"""The benchmark scripts stay importable: a refactor that breaks one fails here, not later."""

import importlib.util
from pathlib import Path
import sys

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / 'benchmarks'


@pytest.mark.parametrize('path', sorted(BENCHMARKS.glob('bench_*.py')), ids=lambda p: p.stem)
def test_benchmark_imports(path, monkeypatch):
    # Importing runs the module's imports and definitions, not the benchmark (main-guarded).
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    spec = importlib.util.spec_from_file_location(f'_bench_{path.stem}', path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)
    spec.loader.exec_module(module)
    assert module.__doc__, f'{path.name} says what it measures in its docstring'
