"""Shared test setup: ROS graph isolation and hypothesis settings."""

import os
import random

from hypothesis import settings
import pytest

# Isolate every test run's DDS traffic before anything imports rclpy: a domain id of our own
# and no discovery beyond this machine. Subprocesses started by the tests inherit both.
if 'TRACKED_KINEMATICS_TEST_DOMAIN' not in os.environ:
    os.environ['TRACKED_KINEMATICS_TEST_DOMAIN'] = str(random.SystemRandom().randint(1, 101))
os.environ['ROS_DOMAIN_ID'] = os.environ['TRACKED_KINEMATICS_TEST_DOMAIN']
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_STATIC_PEERS', None)

# Property tests are about correctness, not speed: no per-example deadline on a busy CI box.
settings.register_profile('tracked', deadline=None, max_examples=200)
settings.load_profile('tracked')


@pytest.fixture
def ros_context():
    """Give one test a fresh rclpy context (in-process nodes take ``context=``)."""
    import rclpy
    context = rclpy.Context()
    rclpy.init(context=context)
    yield context
    rclpy.try_shutdown(context=context)


@pytest.fixture
def executor(ros_context):
    """Give one test a single-threaded executor on its context."""
    from rclpy.executors import SingleThreadedExecutor
    ex = SingleThreadedExecutor(context=ros_context)
    yield ex
    ex.shutdown()
