"""
Benchmark: the real-time factor tracked_simulator achieves, the node run as its console script.

For each asked ``real_time_factor`` (1 to 100), start ``tracked_simulator`` (auriga_alpha,
hard floor, default rates: 100 Hz steps, 50 Hz encoders, 100 Hz gyro, 50 Hz ground truth)
as a subprocess; a probe node in this process sends track setpoints at 50 Hz (an arc, as
cmd_vel_translator would) and records /clock. Over ``WINDOW`` s of wall time it reports:

- the achieved factor: simulated time advanced / wall time elapsed (from the /clock stamps
  and their arrival times);
- the CPU of the node process (utime + stime from /proc/<pid>/stat), in % of one core, and
  per simulated step.

The machine's load counts: on a shared 2-core box the figures move by tens of per cent from
run to run. Runs on the domain of TRACKED_KINEMATICS_TEST_DOMAIN (or ROS_DOMAIN_ID),
localhost only.
"""

import os
from pathlib import Path
import subprocess
import sys
import time

import rclpy
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64

FACTORS = (1.0, 5.0, 10.0, 20.0, 50.0, 100.0)
WINDOW = 8.0  # s of wall time per factor
STEP_RATE = 100.0
TICKS = os.sysconf('SC_CLK_TCK')
SCRIPT = Path(sys.executable).parent / 'tracked_simulator'


def cpu_seconds(pid):
    """Return utime + stime of a process, s."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def measure(factor, env):
    """Return (achieved factor, CPU % of a core, CPU us per step) for one asked factor."""
    process = subprocess.Popen(
        [str(SCRIPT), '--ros-args', '-p', f'real_time_factor:={factor}'],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    node = Node('simulator_bench_probe')
    clock = []
    node.create_subscription(Clock, '/clock', lambda m: clock.append(
        (time.monotonic(), m.clock.sec + m.clock.nanosec * 1e-9)), 100)
    left = node.create_publisher(Float64, 'left_track/setpoint', 10)
    right = node.create_publisher(Float64, 'right_track/setpoint', 10)
    try:
        deadline = time.monotonic() + 30.0
        while not clock and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
        if not clock:
            raise RuntimeError('tracked_simulator did not publish /clock within 30 s')
        # Warm up, then measure.
        start = time.monotonic() + 1.0
        cpu0 = sim0 = wall0 = None
        next_send = time.monotonic()
        while time.monotonic() < start + WINDOW:
            now = time.monotonic()
            if now >= next_send:
                left.publish(Float64(data=0.3))
                right.publish(Float64(data=0.6))
                next_send += 0.02
            rclpy.spin_once(node, timeout_sec=0.005)
            if cpu0 is None and now >= start and clock:
                cpu0, (wall0, sim0) = cpu_seconds(process.pid), clock[-1]
        cpu1, (wall1, sim1) = cpu_seconds(process.pid), clock[-1]
    finally:
        node.destroy_node()
        process.send_signal(2)
        process.wait(10.0)
    wall, sim = wall1 - wall0, sim1 - sim0
    steps = sim * STEP_RATE
    return sim / wall, 100.0 * (cpu1 - cpu0) / wall, 1e6 * (cpu1 - cpu0) / max(steps, 1.0)


def main():
    """Print one row per asked real-time factor."""
    domain = os.environ.get('TRACKED_KINEMATICS_TEST_DOMAIN', os.environ.get('ROS_DOMAIN_ID',
                                                                             '0'))
    env = {**os.environ, 'ROS_DOMAIN_ID': domain, 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
    os.environ.update(env)
    rclpy.init()
    try:
        print(f'{"asked":>6} {"achieved":>9} {"CPU %":>7} {"CPU us/step":>12}')
        for factor in FACTORS:
            achieved, cpu, per_step = measure(factor, env)
            print(f'{factor:6g} {achieved:9.2f} {cpu:7.1f} {per_step:12.1f}')
    finally:
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
