"""offline.plots: every picture of the offline tools is drawn without pyplot's state."""

from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

from helpers.recordings import late
from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.models import ConstantIcr
from tracked_kinematics.offline import plots
from tracked_kinematics.offline.cli import icr_map, plan_trajectory
from tracked_kinematics.offline.errors import UsageError

PNG = b'\x89PNG\r\n\x1a\n'
TERRAIN = Path(__file__).resolve().parents[2] / 'config' / 'auriga_alpha_hard_floor.yaml'


def test_icr_map_plot(tmp_path, capsys, no_pyplot):
    path = tmp_path / 'map.png'
    assert icr_map.main(['packbot', '--n', '5', '--plot', str(path)]) == 0
    assert path.read_bytes()[:8] == PNG


def test_plan_trajectory_plot(tmp_path, capsys, no_pyplot):
    path = tmp_path / 'plan.png'
    # A canonical trajectory: the plot is under test here, the optimiser in its own tests.
    assert plan_trajectory.main(['--params', str(TERRAIN), '--canonical', 'straight',
                                 '--plot', str(path)]) == 0, capsys.readouterr().err
    assert path.read_bytes()[:8] == PNG


def test_heldout_paths_plot(tmp_path, no_pyplot):
    poses = np.column_stack([np.linspace(0, 2, 50), np.zeros(50), np.zeros(50)])
    result = SimpleNamespace(name='path1_random', distance=2.0, truth=poses, ideal=poses + 0.1,
                             identified=poses + 0.01, gyro_aided=poses + 0.02,
                             errors=lambda which: (0.1, 1.0, 5.0))
    path = tmp_path / 'heldout.png'
    plots.plot_heldout_paths(path, [result, result], 'held-out paths')
    assert path.read_bytes()[:8] == PNG


def test_the_held_out_figure_draws_the_gyro_aided_paths_the_demo_reports(tmp_path,
                                                                         monkeypatch):
    # The demo's table reports the gyro-aided errors; its figure once lacked their paths.
    drawn = []
    monkeypatch.setattr(plots, 'save', lambda fig, path, dpi: drawn.append(fig))
    poses = [np.cumsum(np.full((20, 3), k), axis=0) for k in (1.0, 2.0, 3.0, 4.0)]
    result = SimpleNamespace(name='p', distance=5.0, truth=poses[0], ideal=poses[1],
                             identified=poses[2], gyro_aided=poses[3],
                             errors=lambda which: {'gyro_aided': (0.042, 0.0, 0.0)}.get(
                                 which, (1.0, 0.0, 0.0)))
    plots.plot_heldout_paths(tmp_path / 'unused.png', [result], 'title')
    ax = drawn[0].axes[0]
    lines = ax.get_lines()
    assert [line.get_label() for line in lines[:4]] == [
        'ground truth', 'ideal diff drive', 'identified ICRs', 'gyro-aided']
    np.testing.assert_array_equal(lines[3].get_xydata(), poses[3][:, :2])
    assert 'gyro-aided 0.042 m' in ax.get_title()


def test_a_format_matplotlib_cannot_write_is_a_usage_error(tmp_path):
    fig = plots._figure()
    with pytest.raises(UsageError, match=r"p.xyz: Format 'xyz' is not supported \(supported "
                                         r'formats: .*png'):
        plots.save(fig, tmp_path / 'p.xyz', dpi=50)
    assert not (tmp_path / 'p.xyz').exists()
    plots.save(fig, tmp_path / 'p.svg', dpi=50)
    assert (tmp_path / 'p.svg').read_text().lstrip().startswith('<?xml')


@pytest.mark.parametrize('delay', ['auto', 0.1, 'undetermined'])
def test_identification_plot_with_every_kind_of_delay(tmp_path, no_pyplot, delay):
    rec = late(simulate(ConstantIcr(B), np.array(AURIGA), duration=40.0, enc_rate=50.0,
                        seed=2), 0.1)
    result = ident.identify([rec], 'icr_scales', B, holdout=0.0,
                            ground_truth_delay='auto' if delay == 'undetermined' else delay)
    if delay == 'undetermined':
        result.delay = replace(result.delay, determined=False, problem='no motion', delay=0.0)
    segments = ident.build_segments(result.recordings, 1.0)
    path = tmp_path / 'fit.png'
    plots.plot_identification(path, result.recordings, result, segments)
    assert path.read_bytes()[:8] == PNG
