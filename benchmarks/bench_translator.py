"""
Benchmark: cmd_vel_translator latency and CPU, the node run as its console script.

For publish rates of 50 and 200 Hz, start ``cmd_vel_translator`` as a subprocess and, from
a probe node in this process:

- latency: publish Twists at random moments, one to two publish periods apart (random so as
  not to lock onto the node's publishing phase; never two in one period, so that every
  command gets published), each with its own v_x, and time until the first setpoint
  carrying that command arrives back. This is Twist arrival -> next setpoint publish *plus* two
  local DDS hops and the probe's executor, so it is an upper bound of the node's own share;
- CPU of the node process (utime + stime from /proc/<pid>/stat) while idle (no commands,
  the node still publishes at its rate) and under a steady 100 Hz command stream.

For scale, the idle CPU of the conventional design is measured too: an rclpy node that
publishes the same two Float64 from an rclpy timer under ``rclpy.spin``.

Goals (issue 5): p99 latency under one publish period + 1 ms; idle CPU under 1 %.
Runs on the domain of TRACKED_KINEMATICS_TEST_DOMAIN (or ROS_DOMAIN_ID), localhost only.
"""

import os
from pathlib import Path
import random
import subprocess
import sys
import threading
import time

from geometry_msgs.msg import Twist
import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from std_msgs.msg import Float64

RATES = (50.0, 200.0)
SAMPLES = 300
WINDOW = 5.0  # s of each CPU measurement
TICKS = os.sysconf('SC_CLK_TCK')
SCRIPT = Path(sys.executable).parent / 'cmd_vel_translator'
TIMER_NODE = """
import sys, rclpy
from std_msgs.msg import Float64
rclpy.init()
node = rclpy.create_node('timer_reference')
pubs = [node.create_publisher(Float64, t, 10) for t in ('left_ref', 'right_ref')]
node.create_timer(1.0 / float(sys.argv[1]), lambda: [p.publish(Float64()) for p in pubs])
try:
    rclpy.spin(node)
except KeyboardInterrupt:
    pass
"""


def cpu_seconds(pid):
    """CPU time (user + system) used so far by process ``pid``, s."""
    with open(f'/proc/{pid}/stat') as stream:
        fields = stream.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


class Probe(Node):
    """cmd_vel publisher and left setpoint recorder, spun in a thread of its own."""

    def __init__(self):
        super().__init__('translator_bench_probe')
        self.pub = self.create_publisher(Twist, 'cmd_vel', 10)
        self.first_seen = {}
        self.create_subscription(Float64, 'left_track/setpoint', self._on_setpoint, 10)

    def _on_setpoint(self, msg):
        self.first_seen.setdefault(round(msg.data, 9), time.perf_counter())

    def send(self, v_x):
        """Publish a straight-ahead command; return the time it was sent."""
        msg = Twist()
        msg.linear.x = v_x
        sent = time.perf_counter()
        self.pub.publish(msg)
        return sent


def wait_for(condition, timeout=15.0):
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise RuntimeError('cmd_vel_translator did not come up')
        time.sleep(0.01)


def cpu_percent(pid, seconds, action=None, period=None):
    """CPU % of ``pid`` over ``seconds``, calling ``action(k)`` every ``period`` s if given."""
    start_cpu, start = cpu_seconds(pid), time.perf_counter()
    k = 0
    while (now := time.perf_counter()) - start < seconds:
        if action is None:
            time.sleep(seconds - (now - start))
            continue
        action(k)
        k += 1
        time.sleep(max(0.0, start + k * period - time.perf_counter()))
    return 100.0 * (cpu_seconds(pid) - start_cpu) / (time.perf_counter() - start)


def reference_idle_cpu(rate):
    """Idle CPU % of an rclpy node publishing two Float64 from an rclpy timer."""
    node = subprocess.Popen([sys.executable, '-c', TIMER_NODE, str(rate)])
    try:
        time.sleep(2.0)
        return cpu_percent(node.pid, WINDOW)
    finally:
        node.send_signal(2)
        node.wait(10)


def bench(rate, probe):
    """Start the node at ``rate`` and measure it; return the figures."""
    node = subprocess.Popen([str(SCRIPT), '--ros-args', '-p', f'rate:={rate}',
                             '-p', 'cmd_timeout:=0.5', '--log-level', 'warn'])
    try:
        wait_for(lambda: probe.pub.get_subscription_count() > 0 and probe.first_seen)
        time.sleep(1.0)  # let start-up work (imports, discovery) finish before measuring
        idle = cpu_percent(node.pid, WINDOW)
        stream = cpu_percent(node.pid, WINDOW, lambda k: probe.send(0.5 + 1e-4 * (k % 2)),
                             period=0.01)
        latencies = []
        for k in range(SAMPLES):
            v_x = round(1.0 + 1e-3 * k, 9)  # one value per command: no two alike
            sent = probe.send(v_x)
            time.sleep(random.uniform(1.0, 2.0) / rate)
            latencies.append((v_x, sent))
        time.sleep(5.0 / rate + 0.1)
        lat = np.array([probe.first_seen[v] - sent for v, sent in latencies
                        if v in probe.first_seen]) * 1e3
    finally:
        node.send_signal(2)
        node.wait(10)
    return lat, len(latencies) - len(lat), idle, stream


def main():
    """Run the benchmark at every rate and print the figures."""
    domain = os.environ.get('TRACKED_KINEMATICS_TEST_DOMAIN', os.environ.get('ROS_DOMAIN_ID'))
    os.environ['ROS_DOMAIN_ID'] = domain or str(random.SystemRandom().randint(1, 101))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    rclpy.init()
    probe = Probe()
    executor = SingleThreadedExecutor()
    executor.add_node(probe)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        for rate in RATES:
            lat, missed, idle, stream = bench(rate, probe)
            probe.first_seen.clear()
            reference = reference_idle_cpu(rate)
            goal = 1e3 / rate + 1.0
            p99 = np.percentile(lat, 99)
            print(f'bench_translator: rate {rate:g} Hz: latency Twist -> setpoint over '
                  f'{len(lat)} commands: median {np.median(lat):.2f} ms, p99 {p99:.2f} ms '
                  f'(goal < {goal:.1f} ms: {"met" if p99 < goal else "NOT met"}), min '
                  f'{lat.min():.2f} ms, max {lat.max():.2f} ms'
                  f'{f", {missed} never seen" if missed else ""}; CPU idle {idle:.2f} % '
                  f'(goal < 1 %; rclpy-timer reference node {reference:.2f} %), under 100 Hz '
                  f'cmd_vel {stream:.2f} %')
    finally:
        executor.shutdown()
        spinner.join()
        probe.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
