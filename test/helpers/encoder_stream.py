"""Drive encoder topics in lockstep with a node under test, over real rclpy topics."""

from builtin_interfaces.msg import Time
from helpers.ros_helpers import spin_until
from sensor_msgs.msg import JointState

LEFT, RIGHT = 'left_sprocket_joint', 'right_sprocket_joint'


def stamp(t):
    """Return the builtin_interfaces/Time of ``t`` seconds (to the nearest nanosecond)."""
    ns = int(round(t * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def joint_state(t, position=None, velocity=None, names=(LEFT, RIGHT)):
    """Build a JointState at time ``t`` with per-joint positions and/or velocities."""
    msg = JointState()
    msg.header.stamp = stamp(t)
    msg.name = list(names)
    if position is not None:
        msg.position = [float(v) for v in position]
    if velocity is not None:
        msg.velocity = [float(v) for v in velocity]
    return msg


class Driver:
    """
    A node of the test that publishes encoder messages.

    ``send`` publishes one message and spins until the node under test took it in
    (``taken()`` grew), publishing it again if best-effort delivery lost it.
    """

    def __init__(self, ros_context, executor, taken, namespace='', node=None):
        if node is None:
            from rclpy.node import Node
            node = Node('encoder_driver', namespace=namespace, context=ros_context)
            executor.add_node(node)
        self.node = node
        self.executor = executor
        self.taken = taken
        self.publishers = {}

    def publisher(self, msg_type, topic, timeout=5.0):
        """Return a publisher on ``topic``, waiting until the node under test matched it."""
        if topic not in self.publishers:
            pub = self.node.create_publisher(msg_type, topic, 10)
            assert spin_until(self.executor, lambda: pub.get_subscription_count() > 0, timeout)
            self.publishers[topic] = pub
        return self.publishers[topic]

    def send(self, msg, topic='joint_states', attempts=4, timeout=0.5):
        """Publish ``msg`` until the node under test took it in; return True when it did."""
        pub = self.publisher(type(msg), topic)
        before = self.taken()
        for _ in range(attempts):
            pub.publish(msg)
            if spin_until(self.executor, lambda: self.taken() > before, timeout):
                return True
        return False


class Stderr:
    """
    The log lines a test's nodes wrote, read through pytest's ``capfd``.

    rcutils writes each log line to stderr when it is logged, so they can be checked at
    once (throttled repeats are not written at all).
    """

    def __init__(self, capfd):
        self.capfd = capfd
        self.text = ''

    def warnings(self, name, text):
        """Return the WARN lines of logger ``name`` containing ``text`` written so far."""
        return self.lines('WARN', name, text)

    def lines(self, level, name, text):
        """Return the lines of ``level`` (INFO, WARN, ...) of logger ``name`` with ``text``."""
        self.text += self.capfd.readouterr().err
        return [line for line in self.text.splitlines()
                if line.startswith(f'[{level}]') and f'[{name}]' in line and text in line]
