"""Where a tool takes the vehicle's dimensions from two places, another vehicle is refused.

evaluate_model, identify_drivetrain and plan_trajectory have theirs in their own tests; here
identify_icr (--params beside --track-width / --sprocket-radius). The rule:
test/params/test_dimensions.py.
"""

from helpers.vehicle_sim import AURIGA, B, simulate, write_bag
import numpy as np
import pytest
from tracked_kinematics.core.models import ConstantIcr
from tracked_kinematics.offline.cli import identify_icr


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=30.0, seed=4)
    path = tmp_path_factory.mktemp('bags') / 'auriga'
    write_bag(path, rec)
    return path


@pytest.mark.parametrize('option, value, message', [
    ('--track-width', '1.08', 'track_width 1.08 m from --track-width and 0.42 m from '),
    ('--sprocket-radius', '0.3', 'sprocket_radius 0.3 m from --sprocket-radius and 0.1 m from '),
])
def test_identify_icr_refuses_a_base_file_of_another_vehicle(bag, tmp_path, capsys, option,
                                                             value, message):
    base = tmp_path / 'auriga.yaml'
    base.write_text('track_width: 0.42\nsprocket_radius: 0.1\n')
    argv = [bag, '--ground-truth-topic', '/mocap/pose', '--params', base, option, value,
            '--output', tmp_path / 'o.yaml']
    status = identify_icr.main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert status == 2
    assert err.startswith(f'identify_icr: error: {message}{base} differ by ')
    assert err.count('\n') == 1
    assert not (tmp_path / 'o.yaml').exists()
