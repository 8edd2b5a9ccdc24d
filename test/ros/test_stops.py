"""Every node's console script stops cleanly at any instant, input flowing (issue 20)."""

import random
import signal

from helpers import stops
import pytest

# Per node: as soon as the process exists and at random instants of its first 1.5 s, waiting
# for nothing (before and after the package's first line: calibration_drive imported its
# offline code for 1.1 s before it took signals, and died of them or printed a traceback);
# during the start-up (imports, rclpy.init, parameters), and at a random instant of a 1 kHz
# input, signalled once or twice. ``make stress`` runs many more, under load.
CASES = [('at once', (signal.SIGINT,)), ('early', (signal.SIGTERM,)),
         ('early', (signal.SIGINT, signal.SIGTERM)), ('early', (signal.SIGINT,)),
         ('startup', (signal.SIGINT,)), ('startup', (signal.SIGTERM, signal.SIGTERM)),
         ('running', (signal.SIGTERM,)), ('running', (signal.SIGINT, signal.SIGTERM))]


@pytest.fixture
def feeder(ros_domain):
    feeder = stops.Feeder(ros_domain)
    yield feeder
    feeder.close()


#: The nodes whose stops make test checks: none (a signal to each node is tested in its own
#: file, the drive's at two instants); make stress stops every node 40 times at random
#: instants (docs/testing.md).
SUITE_NODES = ()


@pytest.mark.ros
@pytest.mark.parametrize('name', [
    name if name in SUITE_NODES else pytest.param(name, marks=pytest.mark.long)
    for name in sorted(stops.NODES)])
def test_stops_at_random_instants_are_clean(tmp_path, feeder, name):
    rng = random.Random(f'{name}-20')
    for k, (when, signals) in enumerate(CASES):
        stop = stops.stop_once(name, rng, tmp_path / str(k), when=when, signals=signals)
        assert stop.status is not None, f'{name} hung after {stop.signals}'
        # Exit 0 without a traceback; before the package's first line, Python's own course.
        assert stop.clean, (when, stop.signals, stop.delay, stop.before_package, stop.status,
                            stop.output)
        if when == 'running':
            assert stop.up, stop.output
        # A stopped calibration drive never drove: it writes no fit (nor any temporary file).
        assert sorted(p.name for p in (tmp_path / str(k)).iterdir()) == [f'{name}.log']
