"""Shared test setup: a ROS domain of its own for every test, hypothesis settings."""

import contextlib
import os
import signal
import weakref

from helpers import domains
from hypothesis import settings
import pytest

# A suite started in the background of a script (`make test &`) inherits SIGINT ignored, as
# POSIX shells start background jobs, and Python keeps it so; the tests of Ctrl-C (and the
# processes they start) need Python's default handler, as a terminal gives it.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

# No discovery beyond this machine, and no static peers, for every test and its subprocesses.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_STATIC_PEERS', None)

#: ``make stress`` (and ``TRACKED_KINEMATICS_LONG=1``) also runs the tests marked ``long``: the
#: long closed-loop and attack scenarios that ``make test`` leaves out to stay short
#: (docs/testing.md lists them).
LONG = os.environ.get('TRACKED_KINEMATICS_LONG') == '1'

# Property tests are about correctness, not speed: no per-example deadline on a busy CI box.
# make test draws hypothesis's default 100 examples per property, make stress 500 (a test
# that sets its own max_examples keeps it).
settings.register_profile('tracked', deadline=None, max_examples=100)
settings.register_profile('tracked-long', deadline=None, max_examples=500)
settings.load_profile('tracked-long' if LONG else 'tracked')


@pytest.fixture(autouse=True)
def ros_domain(monkeypatch):
    """
    Give every test a ROS domain id that no other test, here or in another process, holds.

    It is set as ``ROS_DOMAIN_ID`` for the test (rclpy reads it when a context is
    initialised) and for the subprocesses it starts, so that no publisher, subscription or
    parameter service of one test is ever in the graph of another. The id is given back once
    the test has torn down (fixtures tear down in reverse order: this one last).
    """
    with domains.acquire() as lease:
        monkeypatch.setenv('ROS_DOMAIN_ID', str(lease.domain_id))
        yield lease.domain_id


@pytest.fixture
def ros_context(ros_domain, monkeypatch):
    """Give one test a fresh rclpy context on its own domain (nodes take ``context=``)."""
    import rclpy
    from rclpy.node import Node
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=ros_domain)
    # A node the test left behind (a failed start in a helper, say) is destroyed here, while
    # its context is still up, not by a collection after the shutdown. Each node is noted as
    # it is made: a full gc.collect() here cost up to 0.1 s a test, 10-35 s of the suite's CPU.
    made = []
    init = Node.__init__

    def noted(self, *args, **kwargs):
        made.append(weakref.ref(self))
        init(self, *args, **kwargs)

    monkeypatch.setattr(Node, '__init__', noted)
    yield context
    for ref in made:
        node = ref()
        with contextlib.suppress(Exception):   # destroyed already, or half made
            if node is not None and node.context is context:
                node.destroy_node()
    rclpy.try_shutdown(context=context)


@pytest.fixture
def executor(ros_context):
    """Give one test a single-threaded executor on its context."""
    from rclpy.executors import SingleThreadedExecutor
    ex = SingleThreadedExecutor(context=ros_context)
    yield ex
    ex.shutdown()


#: The test files that take longest (20-100 s each on a quiet machine), run first: pytest-xdist
#: (``--dist loadfile``) hands the files out in collection order, and a long file handed out
#: last keeps one worker busy while the others have nothing left (the longest first is
#: the classic schedule). Order only: every file runs as before.
LONGEST_FIRST = (
    'test/ros/test_calibration_drive.py', 'test/offline/test_identify_reference.py',
    'test/ros/test_cmd_vel_translator.py', 'test/ros/test_odometry_node_imu_input.py',
    'test/package/test_packaging.py', 'test/offline/test_identify_cli.py',
    'test/offline/test_realdata_consistency.py', 'test/ros/test_tracked_simulator.py',
    'test/offline/test_identify_noise.py', 'test/ros/test_health.py',
    'test/offline/test_demo.py', 'test/package/test_lint.py', 'test/ros/test_play_bag.py',
    'test/core/identify/test_drivetrain_fit.py', 'test/offline/test_realdata_pose_gyro.py',
    'test/offline/test_simulate_bag.py', 'test/core/identify/test_identification.py',
    'test/package/test_architecture.py')


def _longest_first(items):
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split('::')[0], len(rank)))


def pytest_collection_modifyitems(config, items):
    """
    Run the longest files first; skip the ``long`` tests unless ``TRACKED_KINEMATICS_LONG=1``.

    The ``long`` ones are skipped with the reason.
    """
    _longest_first(items)
    if LONG:
        return
    skip = pytest.mark.skip(reason='long scenario: make stress (TRACKED_KINEMATICS_LONG=1) '
                                   'runs it')
    for item in items:
        if 'long' in item.keywords:
            item.add_marker(skip)
