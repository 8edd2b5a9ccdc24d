"""Every node's console script stops cleanly at any instant, input flowing (issue 20)."""

import random
import signal

from helpers import stops
import pytest

# Per node: during the start-up (imports, rclpy.init, parameters), and at a random instant
# of a 1 kHz input, signalled once or twice. ``make stress`` runs many more, under load.
CASES = [('startup', (signal.SIGINT,)), ('startup', (signal.SIGTERM, signal.SIGTERM)),
         ('running', (signal.SIGTERM,)), ('running', (signal.SIGINT, signal.SIGTERM))]


@pytest.fixture
def feeder(ros_domain):
    feeder = stops.Feeder(ros_domain)
    yield feeder
    feeder.close()


@pytest.mark.ros
@pytest.mark.parametrize('name', sorted(stops.NODES))
def test_stops_at_random_instants_are_clean(tmp_path, feeder, name):
    rng = random.Random(f'{name}-20')
    for k, (when, signals) in enumerate(CASES):
        stop = stops.stop_once(name, rng, tmp_path / str(k), when=when, signals=signals)
        assert stop.status is not None, f'{name} hung after {stop.signals}'
        assert stop.clean, (when, stop.signals, stop.delay, stop.status, stop.output)
        if when == 'running':
            assert stop.up, stop.output
        # A stopped calibration drive never drove: it writes no fit (nor any temporary file).
        assert sorted(p.name for p in (tmp_path / str(k)).iterdir()) == [f'{name}.log']
