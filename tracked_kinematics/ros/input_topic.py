"""
An input subscription that follows its publishers: reliability, depth, wrong types.

Reliable when all publishers are, best effort otherwise; re-subscribes without losing or
repeating a sample. See docs/nodes/odometry_node.md ("QoS: no sample lost from a reliable
publisher").
"""

from __future__ import annotations

from collections.abc import Callable
from time import monotonic_ns

from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.exceptions import InvalidHandle
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from tracked_kinematics.ros.health import MessageCount

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
    order_key : callable, optional
        ``order_key(msg) -> int`` telling samples apart (the stamp in ns). During a switch the
        old subscription delivers until it has passed on a message the new one holds too, and
        each sample is passed on once. Without it a sample or two in flight may be lost.

    Attributes
    ----------
    topic_name : str
        The resolved topic name.
    reliability : rclpy.qos.ReliabilityPolicy
        Reliability of the current subscription.
    count : MessageCount
        Messages passed on, and when the last one was (for the node's health).

    """

    def __init__(self, node, msg_type, topic: str, callback: Callable, depth: int = INPUT_DEPTH,
                 order_key: Callable | None = None, raw: bool = False, drain: int = 0):
        self._node = node
        self._msg_type = msg_type
        self.count = MessageCount()
        self._callback = callback
        self._counted = self.count.counted(callback)
        self._depth = depth
        self._order_key = order_key
        self._raw = raw
        self._drain = drain
        self.type_name = type_name(msg_type)
        self.topic_name = node.resolve_topic_name(topic)
        self.reliability = self._wanted() or ReliabilityPolicy.BEST_EFFORT
        self._subscription = self._subscribe(self.reliability, self._steady_callback)
        self._old = None  # the subscription being replaced, while it is
        self._expected = 0
        self._passed: set = set()
        self._buffer: list = []
        self._old_traffic = False
        self._warned_types: set = set()

    def _subscribe(self, reliability, callback):
        # A publisher whose QoS cannot match (a best-effort one for a reliable subscription)
        # is followed at once, not at the next check.
        events = SubscriptionEventCallbacks(incompatible_qos=self._on_incompatible)
        return self._node.create_subscription(self._msg_type, self.topic_name, callback,
                                              input_qos(reliability, self._depth),
                                              event_callbacks=events, raw=self._raw)

    def _on_incompatible(self, event) -> None:
        self.check()

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
        if self._old is not None:
            # Without an order of the messages, or when the old subscription received
            # nothing since the last check (nothing can be pending in it, e.g. its QoS no
            # longer matches any publisher), it goes once the new one has matched.
            if (self._order_key is None or not self._old_traffic) and self._matched():
                self._retire()
            self._old_traffic = False
            return
        wanted = self._wanted(infos)
        if wanted is None or wanted == self.reliability:
            return
        # The new subscription first; the old one keeps delivering until it has caught up
        # with what the new one holds (then it is destroyed), so the switch loses no sample.
        self._expected = sum(1 for info in infos if info.topic_type == self.type_name)
        self._passed = set()
        self._buffer = []
        self._old_traffic = False
        self._old = self._subscription
        self._old.callback = self._on_old
        self._subscription = self._subscribe(wanted, self._on_new)
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
    def switching(self) -> bool:
        """Whether an old subscription is still being replaced."""
        return self._old is not None

    def _matched(self) -> bool:
        try:
            return self._subscription.get_publisher_count() >= self._expected
        except Exception:  # noqa: BLE001 -- shutting down
            return False

    def _retire(self) -> None:
        """Destroy the old subscription; pass on what the new one held back, in order."""
        self._node.destroy_subscription(self._old)
        self._old = None
        buffer, self._buffer = self._buffer, []
        for key, msg in buffer:
            self._pass_on(msg, key)
        # Messages the old one passed on may still wait in the new one's queue: drop those
        # until the first new one, then hand the callback over.
        self._subscription.callback = self._steady_callback if self._order_key is None \
            else self._on_new_after

    def _pass_on(self, msg, key) -> bool:
        """Pass a message on unless it was passed on already during the switch."""
        if key in self._passed:
            return False
        self._passed.add(key)
        self._counted(msg)
        return True

    def _on_old(self, msg) -> None:
        self._old_traffic = True
        if self._order_key is None:
            self._counted(msg)
            return
        key = self._order_key(msg)
        self._pass_on(msg, key)
        if self._buffer and self._buffer[0][0] == key:
            # The new subscription holds this one too: the old one has delivered everything
            # that only it had (a subscription delivers in order). It can go.
            self._buffer.pop(0)
            self._retire()

    def _on_new(self, msg) -> None:
        if self._order_key is None:
            return  # the old subscription delivers until it is retired
        key = self._order_key(msg)
        if key in self._passed:
            self._retire()  # the old one got here first: nothing is left only in it
        else:
            self._buffer.append((key, msg))

    def _on_new_after(self, msg) -> None:
        if self._pass_on(msg, self._order_key(msg)):
            self._passed = set()
            self._subscription.callback = self._steady_callback

    @property
    def _steady_callback(self) -> Callable:
        """Return the callback of the subscription when no switch is under way."""
        return self._drained if self._drain else self._counted

    def _drained(self, msg) -> None:
        """Pass on ``msg``, then up to ``drain`` messages that wait in the queue after it."""
        # Counted inline (one clock read per turn): this is odometry_node's hot path.
        count = self.count
        count.last_ns = monotonic_ns()
        count.count += 1
        callback = self._callback
        callback(msg)
        handle = self._subscription.handle
        for _ in range(self._drain):
            try:
                with handle:
                    taken = handle.take_message(self._msg_type, self._raw)
            except InvalidHandle:  # destroyed (the node is shutting down)
                return
            if taken is None:
                return
            count.count += 1
            callback(taken[0])

    @property
    def subscription(self):
        """Return the current subscription."""
        return self._subscription
