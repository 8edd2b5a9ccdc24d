"""
An input subscription that follows its publishers: reliability, depth, wrong types.

DDS matches a subscription to a publisher only when their QoS are compatible: a reliable
subscription receives nothing from a best-effort (sensor-data) publisher, and a best-effort
subscription to a reliable publisher lets the middleware drop samples whenever the node falls
behind. :class:`InputTopic` subscribes with the reliability its publishers offer, reliable when
they all are (joint_state_broadcaster, most drivers: then no sample they send is lost) and
best effort as soon as one is not (sensor-data publishers keep working), and with a queue deep
enough for a second of input at 1 kHz. :meth:`InputTopic.check`, called about once a second,
re-subscribes when the publishers change, and names publishers of another message type on the
topic, whose messages DDS silently never delivers.
"""

from __future__ import annotations

from collections.abc import Callable

from rclpy.clock import Clock, ClockType
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# Queue of an input subscription: one second at 1 kHz (ros2_control's fastest common update
# rate), ten at 100 Hz, so a node that falls behind for that long catches up without a loss.
INPUT_DEPTH = 1000

# Period of the graph checks, s (a steady clock: they run under sim time too).
CHECK_PERIOD = 1.0

# Seconds between two warnings about the same problem.
WARN_PERIOD = 5.0


def type_name(msg_type) -> str:
    """Return the ROS name of a message class: ``sensor_msgs/msg/JointState``."""
    return f'{msg_type.__module__.split(".")[0]}/msg/{msg_type.__name__}'


def steady_timer(node, period: float, callback):
    """Create a timer of ``node`` on the steady clock (it fires under sim time too)."""
    return node.create_timer(period, callback, clock=Clock(clock_type=ClockType.STEADY_TIME))


def input_qos(reliability: ReliabilityPolicy, depth: int = INPUT_DEPTH) -> QoSProfile:
    """Return the QoS of an input subscription of the given reliability."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=reliability,
                      durability=DurabilityPolicy.VOLATILE)


def _endpoint(info) -> str:
    namespace = info.node_namespace.rstrip('/')
    return f'{namespace}/{info.node_name}' if info.node_name else '(unknown node)'


class InputTopic:
    """
    Subscribe to an input topic with the QoS its publishers offer; warn about wrong types.

    Parameters
    ----------
    node : rclpy.node.Node
        Owner of the subscription and the logger.
    msg_type : type
        Message class.
    topic : str
        Topic name (relative names are resolved as usual).
    callback : callable
        Message callback.
    depth : int
        Queue depth.

    Attributes
    ----------
    topic_name : str
        The resolved topic name.
    reliability : rclpy.qos.ReliabilityPolicy
        Reliability of the current subscription.

    """

    def __init__(self, node, msg_type, topic: str, callback: Callable, depth: int = INPUT_DEPTH):
        self._node = node
        self._msg_type = msg_type
        self._callback = callback
        self._depth = depth
        self.type_name = type_name(msg_type)
        self.topic_name = node.resolve_topic_name(topic)
        self.reliability = self._wanted() or ReliabilityPolicy.BEST_EFFORT
        self._subscription = self._subscribe(self.reliability)
        self._warned_types: set = set()

    def _subscribe(self, reliability):
        return self._node.create_subscription(self._msg_type, self.topic_name, self._callback,
                                              input_qos(reliability, self._depth))

    def _publishers(self):
        try:
            return self._node.get_publishers_info_by_topic(self.topic_name)
        except Exception:  # noqa: BLE001 -- the graph is gone during shutdown
            return []

    def _wanted(self, infos=None):
        """Reliability the publishers of our type offer, or None without publishers."""
        infos = self._publishers() if infos is None else infos
        ours = [info for info in infos if info.topic_type == self.type_name]
        if not ours:
            return None
        if all(info.qos_profile.reliability == ReliabilityPolicy.RELIABLE for info in ours):
            return ReliabilityPolicy.RELIABLE
        return ReliabilityPolicy.BEST_EFFORT

    def check(self) -> None:
        """Follow the publishers' reliability; warn about publishers of another type."""
        infos = self._publishers()
        wrong = sorted({(info.topic_type, _endpoint(info)) for info in infos
                        if info.topic_type != self.type_name})
        if wrong and tuple(wrong) not in self._warned_types:
            self._warned_types.add(tuple(wrong))
            others = ', '.join(f'{kind} from {who}' for kind, who in wrong)
            self._node.get_logger().warning(
                f'{self.topic_name} has publishers of another message type ({others}); this '
                f'node subscribes {self.type_name}: their messages are never received. '
                'Remap the topic or fix the publisher.')
        wanted = self._wanted(infos)
        if wanted is None or wanted == self.reliability:
            return
        old = self._subscription
        # The new subscription first: a sample delivered to both is a duplicate, which the
        # encoder input recognises by its stamp, rather than a loss.
        self._subscription = self._subscribe(wanted)
        self._node.destroy_subscription(old)
        self.reliability = wanted
        if wanted == ReliabilityPolicy.RELIABLE:
            self._node.get_logger().info(
                f'{self.topic_name}: all publishers are reliable: subscribed reliable '
                f'(depth {self._depth}), no sample they send is dropped')
        else:
            self._node.get_logger().info(
                f'{self.topic_name}: a publisher is best effort (sensor data): subscribed best '
                'effort, samples may be dropped under load')

    @property
    def subscription(self):
        """Return the current subscription."""
        return self._subscription
