"""
Benchmark: odometry_node throughput and latency against a bare rclpy relay.

Two processes on one ROS domain (localhost only): the node under test, and this script,
which publishes sensor_msgs/JointState to it and receives its output. The node under test
is either ``odometry_node`` (JointState -> nav_msgs/Odometry) or the *relay*, the ceiling
for Python on this machine: a bare rclpy node that republishes each JointState it receives,
with the node's QoS in and out and the default executor. Its input keeps 1000 messages as
the node's does (best effort, as the node follows a sensor-data publisher): with the
sensor-data depth of 5 it would drop the messages that wait longest whenever it falls
behind, the very ones that make the tail, and its p99 would be of the survivors only. This
script receives raw bytes (no deserialisation), reads only the header stamp and takes all
the output that waits in one turn of its executor, so that it stays lighter than either node.

- flood: JointState as fast as the node takes them, with a window of at most three
  messages in flight (sensor-data QoS, which the node's input follows; its queue
  keeps 1000, so none is dropped for lack of room); the figures are messages handled
  per second and the node process's CPU time per message (/proc), which other load on
  the machine disturbs less.
- 1 kHz: JointState paced at 1000 Hz; the figures are the median and the 99th percentile
  of the latency from the input's header.stamp (wall clock at publishing) to the receipt of
  the output here, an upper bound of stamp-to-publish, and the messages lost (none should).

- with the IMU (issue 29): odometry_node again, with ``imu_topic`` set and a
  sensor_msgs/Imu published at 400 Hz (wall clock) beside the encoders, reliable; the
  figures are those of the node alone, their ratios to them (goal: within 10 %), and the
  Imu messages the node did not receive (its ``/diagnostics`` count against those sent:
  none should be lost).

The load of the machine (other jobs) moves every figure, so the two are compared in pairs:
each run measures odometry_node and then the relay, one right after the other, and gives
two ratios, the flood ratio (node's rate / relay's) and the p99 ratio (node's p99 / relay's);
``--repeats`` such runs (three by default) print their medians. Goals (issue 20): flood
ratio >= 90 %, p99 ratio <= 1.5. Every line carries the load average it ran under.
Usage: ``python benchmarks/bench_odometry_node.py [--count N] [--seconds S] [--repeats R]``.
"""

import argparse
import os
import random
import statistics
import struct
import subprocess
import sys
import time

# One domain of our own, on this machine only, before rclpy is imported.
os.environ.setdefault('ROS_DOMAIN_ID', os.environ.get(
    'TRACKED_KINEMATICS_TEST_DOMAIN', str(random.SystemRandom().randint(1, 101))))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

import rclpy  # noqa: E402,I100 -- after the environment above
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy  # noqa: E402

RELIABLE = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
STAMP = struct.Struct('<iI')
BIN = os.path.dirname(sys.executable)


RELAY = 'relay'
NODE = 'odometry_node'
NODE_IMU = 'odometry+imu'
IMU_RATE = 400.0  # Hz


def relay() -> None:
    """Run the relay: a bare rclpy node that republishes every JointState it receives."""
    from sensor_msgs.msg import JointState
    from tracked_kinematics.ros.input_topic import input_qos
    rclpy.init()
    node = rclpy.create_node('bench_relay')
    pub = node.create_publisher(JointState, 'odom', QoSProfile(depth=10))
    node.create_subscription(JointState, 'joint_states', pub.publish,
                             input_qos(ReliabilityPolicy.BEST_EFFORT))
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        try:
            rclpy.try_shutdown()
        except Exception:  # noqa: BLE001 -- the signal's own shutdown may have raced this one
            pass


def _joint_state(i, stamp_ns):
    from sensor_msgs.msg import JointState
    msg = JointState()
    msg.name = ['left_sprocket_joint', 'right_sprocket_joint']
    msg.position = [0.01 * i, 0.012 * i]
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    return msg


def cpu_seconds(pid: int) -> float:
    """User + system CPU time a process has used so far, s (Linux /proc)."""
    with open(f'/proc/{pid}/stat') as stat:
        fields = stat.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


class ImuFeed:
    """Imu messages at :data:`IMU_RATE` Hz (wall clock), and what the node counted of them."""

    def __init__(self, node):
        from diagnostic_msgs.msg import DiagnosticArray
        from sensor_msgs.msg import Imu
        self.pub = node.create_publisher(Imu, 'imu', RELIABLE)
        self.msg = Imu()
        self.sent = 0
        self.counted = None
        self.next = time.monotonic()
        node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics, 10)

    def _on_diagnostics(self, array) -> None:
        for status in array.status:
            for value in status.values:
                if value.key == '/imu messages':
                    self.counted = int(value.value)

    def tick(self) -> None:
        """Publish the samples due by now."""
        now = time.monotonic()
        while self.next <= now:
            self.msg.header.stamp.sec, self.msg.header.stamp.nanosec = divmod(
                time.time_ns(), 1_000_000_000)
            self.msg.angular_velocity.z = 0.01
            self.pub.publish(self.msg)
            self.sent += 1
            self.next += 1.0 / IMU_RATE

    def wait(self, seconds: float) -> float:
        """Return how long to wait at most for the next sample (s), up to ``seconds``."""
        return max(0.0, min(seconds, self.next - time.monotonic()))


def measure(target: str, count: int, rate: float):
    """
    Run one target; return (messages/s, CPU s per message of the node, latencies in ms, Imu lost).

    ``rate`` 0 floods with a window of three messages in flight; otherwise the messages
    are paced at ``rate`` Hz.
    """
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import JointState
    if target in (NODE, NODE_IMU):
        command = [os.path.join(BIN, 'odometry_node'), '--ros-args', '-p', 'publish_tf:=false',
                   '-p', 'track_width:=0.42', '-p', 'sprocket_radius:=0.1',
                   '--log-level', 'error']
        if target == NODE_IMU:
            command[2:2] = ['-p', 'imu_topic:=imu']
        output_type = Odometry
    else:
        command = [sys.executable, __file__, '--role', RELAY]
        output_type = JointState
    server = subprocess.Popen(command)
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('bench_driver', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    received = []

    def on_output(data):
        # CDR (little-endian here): 4 bytes of encapsulation, then header.stamp. Whatever
        # else waits is taken at once too, so that a burst of output (a node catching up)
        # is timed when it arrives, not when this script's executor gets round to it.
        while data is not None:
            sec, nanosec = STAMP.unpack_from(data, 4)
            received.append((time.time_ns(), sec * 1_000_000_000 + nanosec))
            with sub.handle:
                taken = sub.handle.take_message(output_type, True)
            data = taken and taken[0]

    pub = node.create_publisher(JointState, 'joint_states', qos_profile_sensor_data)
    sub = node.create_subscription(output_type, 'odom', on_output, RELIABLE, raw=True)
    imu = ImuFeed(node) if target == NODE_IMU else None
    tick = imu.tick if imu is not None else (lambda: None)
    lost_imu = 0
    try:
        deadline = time.monotonic() + 20.0
        while ((sub.get_publisher_count() == 0 or pub.get_subscription_count() == 0
                or (imu is not None and imu.pub.get_subscription_count() == 0))
               and time.monotonic() < deadline):
            executor.spin_once(timeout_sec=0.01)
        if imu is not None:
            # The node follows the reliable Imu publisher at its next graph check (1 s).
            # Samples sent before both ends matched may be lost in discovery, not by the
            # node: a pause, and the node's count once it is up to date, set the baseline.
            settle = time.monotonic() + 1.5
            imu.next = time.monotonic()
            while time.monotonic() < settle:
                tick()
                executor.spin_once(timeout_sec=imu.wait(0.01))
            imu.counted = None
            paused = time.monotonic() + 2.5
            while imu.counted is None and time.monotonic() < paused:
                executor.spin_once(timeout_sec=0.05)
            imu.counted = None
            while imu.counted is None and time.monotonic() < paused:
                executor.spin_once(timeout_sec=0.05)
            baseline = imu.sent - (imu.counted or 0)
            imu.next = time.monotonic()
        # A first message settles discovery on both sides; then the clock starts.
        while not received and time.monotonic() < deadline:
            pub.publish(_joint_state(0, time.time_ns()))
            executor.spin_once(timeout_sec=0.2)
        if not received:
            raise RuntimeError(f'{target} published nothing')
        received.clear()
        start = time.monotonic()
        start_ns = time.time_ns()
        start_cpu = cpu_seconds(server.pid)
        if rate:
            for i in range(1, count + 1):
                due = start + i / rate
                while (wait := due - time.monotonic()) > 0:
                    executor.spin_once(timeout_sec=imu.wait(wait) if imu else wait)
                    tick()
                pub.publish(_joint_state(i, time.time_ns()))
        else:
            sent = 0
            progress = time.monotonic()
            while sent < count and time.monotonic() < deadline + 60.0:
                tick()
                if sent - len(received) < 3:
                    sent += 1
                    pub.publish(_joint_state(sent, time.time_ns()))
                    continue
                before = len(received)
                executor.spin_once(timeout_sec=0.05)
                if len(received) > before:
                    progress = time.monotonic()
                elif time.monotonic() - progress > 0.2:  # lost in transit: resume
                    sent = len(received)
                    progress = time.monotonic()
        end = time.monotonic() + 1.0
        while len(received) < count and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
        elapsed = (received[-1][0] - start_ns) * 1e-9 if received else float('inf')
        cpu = (cpu_seconds(server.pid) - start_cpu) / max(len(received), 1)
        if imu is not None:
            # The node's count on /diagnostics (once a second) catches up with what was sent.
            end = time.monotonic() + 3.0
            while (imu.counted is None or imu.counted < imu.sent) and time.monotonic() < end:
                executor.spin_once(timeout_sec=0.05)
            lost_imu = imu.sent - (imu.counted or 0) - baseline
    finally:
        server.send_signal(subprocess.signal.SIGINT)
        server.wait(10)
        executor.shutdown()
        rclpy.try_shutdown(context=context)
    latencies = [(recv - stamp) * 1e-6 for recv, stamp in received]
    return len(received) / elapsed, cpu, latencies or [float('nan')], lost_imu


def p99(values):
    """Return the 99th percentile."""
    return statistics.quantiles(values, n=100)[98]


def load() -> str:
    """Return the load averages over 1, 5 and 15 minutes, as uptime prints them."""
    return ', '.join(f'{value:.2f}' for value in os.getloadavg())


def run_pair(count: int, seconds: float):
    """
    Measure odometry_node and the relay, each right after the other; return their figures.

    The two floods run one after the other, then the two 1 kHz runs, so that each ratio
    compares measurements a few seconds apart. Each target's figures are (flood msg/s, node
    CPU s per message in the flood, 1 kHz latency median ms, 1 kHz latency p99 ms, messages
    lost at 1 kHz).
    """
    flood = {target: measure(target, count, 0.0) for target in TARGETS}
    figures = {}
    sent = int(seconds * 1000)
    for target in TARGETS:
        _, _, latencies, lost_imu = measure(target, sent, 1000.0)
        figures[target] = (*flood[target][:2], statistics.median(latencies), p99(latencies),
                           sent - len(latencies), flood[target][3] + lost_imu)
    return figures


TARGETS = (NODE, NODE_IMU, RELAY)


def _line(target, figures) -> str:
    rate, cpu, median, late, lost, lost_imu = figures
    return (f'{target:13s} flood {rate:6.0f} msg/s, CPU {1e6 * cpu:4.0f} us/msg; at 1 kHz '
            f'latency median {median:.3f} ms, p99 {late:.3f} ms, {lost:.0f} lost'
            + (f'; Imu lost {lost_imu:.0f}' if target == NODE_IMU else ''))


def main():
    """Parse arguments, run the roles or the benchmark, print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument('--role', choices=('bench', RELAY), default='bench',
                        help=argparse.SUPPRESS)
    parser.add_argument('--count', type=int, default=5000, help='messages per flood')
    parser.add_argument('--seconds', type=float, default=3.0, help='length of the 1 kHz run')
    parser.add_argument('--repeats', type=int, default=3,
                        help='runs, each measuring odometry_node and then the relay')
    args = parser.parse_args()
    if args.role == RELAY:
        return relay()
    name = 'bench_odometry_node:'
    runs = []
    for i in range(1, args.repeats + 1):
        figures = run_pair(args.count, args.seconds)
        runs.append(figures)
        node, gyro, bare = figures[NODE], figures[NODE_IMU], figures[RELAY]
        for target in TARGETS:
            print(f'{name} run {i}: {_line(target, figures[target])}', flush=True)
        print(f'{name} run {i}: flood ratio {100 * node[0] / bare[0]:.0f} %, p99 ratio '
              f'{node[3] / bare[3]:.2f}; with the IMU / without: flood '
              f'{100 * gyro[0] / node[0]:.0f} %, p99 {gyro[3] / node[3]:.2f}; load average '
              f'{load()}', flush=True)
    for target in TARGETS:
        medians = tuple(statistics.median(run[target][k] for run in runs) for k in range(6))
        print(f'{name} median of {args.repeats}: {_line(target, medians)}')
    flood = statistics.median(run[NODE][0] / run[RELAY][0] for run in runs)
    late = statistics.median(run[NODE][3] / run[RELAY][3] for run in runs)
    print(f'{name} odometry_node vs relay, median of {args.repeats} runs: flood ratio '
          f'{100 * flood:.0f} % (goal >= 90 %), p99 ratio {late:.2f} (goal <= 1.5); load '
          f'average {load()} on {os.cpu_count()} cores')
    flood = statistics.median(run[NODE_IMU][0] / run[NODE][0] for run in runs)
    late = statistics.median(run[NODE_IMU][3] / run[NODE][3] for run in runs)
    cpu = statistics.median(run[NODE_IMU][1] / run[NODE][1] for run in runs)
    lost = max(run[NODE_IMU][5] for run in runs)
    print(f'{name} with a {IMU_RATE:.0f} Hz IMU vs without, median of {args.repeats} runs: '
          f'flood ratio {100 * flood:.0f} % (goal >= 90 %), p99 ratio {late:.2f} (goal <= '
          f'1.1), CPU per encoder message ratio {cpu:.2f}; Imu messages lost at most '
          f'{lost:.0f} (goal 0)')


if __name__ == '__main__':
    main()
