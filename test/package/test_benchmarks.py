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


def test_bench_gyro_sets_fits_with_identify_icrs_own_options(monkeypatch):
    # Its files once came from the library's defaults (no ground-truth delay removed), not the
    # tool's: the ICP's 0.2-s latency went into the noise model's timing and the gyro-aided
    # covariance looked too large (issue 35). Its options are identify_icr's command line's.
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    path = BENCHMARKS / 'bench_gyro_sets.py'
    spec = importlib.util.spec_from_file_location('_bench_gyro_sets_options', path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)
    spec.loader.exec_module(module)
    from tracked_kinematics.offline.cli import identify_icr
    options = module.fit_options(['a', 'b'], 0.3, 1.08, 'grass')
    assert options.identify.ground_truth_delay == 'auto'
    args = identify_icr.build_parser().parse_args(
        ['a', 'b', '--ground-truth-topic', '/icp/pose', '--sprocket-radius', '0.3',
         '--track-width', '1.08', '--terrain', 'grass', '--accept-uncertain', '--output',
         'x.yaml'])
    assert options == identify_icr.options_from_args(args)
