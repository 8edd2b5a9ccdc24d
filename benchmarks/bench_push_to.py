"""
Benchmark: odometry_node's push_to in closed loop (issue 29), with the simulator.

tracked_simulator (auriga_alpha on ``--terrain``, grass by default: chi 0.36), a
cmd_vel_translator and an odometry_node (gyro on imu/data), all loaded with the hard-floor
terrain file (chi 0.54: yesterday's ground), all in sim time. This script commands a steady
turn on cmd_vel and measures, from the simulator's ground truth over the second half of the
drive, the yaw rate and forward speed the robot really makes. Twice: odometry_node without
``push_to`` (the translator keeps the file's ICRs), then with ``push_to:=[cmd_vel_translator]``
(the ICR spread the node adapts from the gyro reaches the translator). Prints the yaw-rate
error against the command in both runs. Usage:
``python benchmarks/bench_push_to.py [--terrain grass] [--seconds 60] [--rtf 2]``.
"""

import argparse
import math
import os
from pathlib import Path
import random
import subprocess
import sys
import tempfile
import time

# One domain of our own, on this machine only, before rclpy is imported.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
TERRAIN_FILE = ROOT / 'config' / 'auriga_alpha_hard_floor.yaml'
V, W = 0.3, 0.4   # the commanded turn: m/s, rad/s


def start(name, *args, log_dir):
    out = open(Path(log_dir) / f'{name}.log', 'w')
    return subprocess.Popen([str(BIN / name), *map(str, args)], stdout=out,
                            stderr=subprocess.STDOUT,
                            env={**os.environ, 'PYTHONUNBUFFERED': '1'})


def run(terrain: str, seconds: float, rtf: float, push: bool, log_dir) -> dict:
    """Drive one steady turn; return the true yaw rate and speed over its second half."""
    import rclpy
    from geometry_msgs.msg import Twist
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    os.environ['ROS_DOMAIN_ID'] = str(random.SystemRandom().randint(1, 101))
    sim_time = ['-p', 'use_sim_time:=true']
    processes = [
        start('tracked_simulator', '--ros-args', '-p', f'terrain:={terrain}',
              '-p', f'real_time_factor:={rtf}', '-p', 'seed:=1', log_dir=log_dir),
        start('cmd_vel_translator', '--ros-args', '--params-file', TERRAIN_FILE, *sim_time,
              '-p', 'cmd_timeout:=2.0', log_dir=log_dir),
        start('odometry_node', '--ros-args', '--params-file', TERRAIN_FILE, *sim_time,
              '-p', 'imu_topic:=imu/data', '-p', 'publish_tf:=false',
              '-p', f'push_to:={["cmd_vel_translator"] if push else []}'.replace("'", ''),
              log_dir=log_dir),
    ]
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('bench_push_to', context=context,
                             parameter_overrides=[Parameter('use_sim_time', value=True)])
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    truth = []
    node.create_subscription(Odometry, 'ground_truth/odom', truth.append, 100)
    cmd = node.create_publisher(Twist, 'cmd_vel', 10)
    twist = Twist()
    twist.linear.x, twist.angular.z = V, W
    try:
        deadline = time.monotonic() + 60.0
        while (not truth or cmd.get_subscription_count() == 0) and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        if not truth:
            raise RuntimeError(f'no ground truth from the simulator (logs in {log_dir})')
        t0 = node.get_clock().now().nanoseconds * 1e-9
        last = 0.0
        while True:
            executor.spin_once(timeout_sec=0.01)
            now = node.get_clock().now().nanoseconds * 1e-9
            if now - last >= 0.05:
                cmd.publish(twist)
                last = now
            if now - t0 >= seconds:
                break
    finally:
        cmd.publish(Twist())
        for process in processes:
            process.send_signal(2)
        for process in processes:
            try:
                process.wait(10.0)
            except subprocess.TimeoutExpired:
                process.kill()
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
    stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in truth]
    half = stamps[0] + 0.5 * (stamps[-1] - stamps[0])
    second = [m for m, t in zip(truth, stamps) if t >= half]
    yaw_rate = sum(m.twist.twist.angular.z for m in second) / len(second)
    speed = sum(math.hypot(m.twist.twist.linear.x, m.twist.twist.linear.y)
                for m in second) / len(second)
    return {'yaw_rate': yaw_rate, 'speed': speed}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--terrain', default='grass')
    parser.add_argument('--seconds', type=float, default=60.0, help='sim time per run')
    parser.add_argument('--rtf', type=float, default=2.0, help='real-time factor')
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as logs:
        logs = os.environ.get('BENCH_LOGS', logs)  # keep the nodes' logs there
        results = {push: run(args.terrain, args.seconds, args.rtf, push, logs)
                   for push in (False, True)}
    print(f'closed loop on {args.terrain} with the hard-floor file, cmd v {V} m/s, w {W} rad/s, '
          f'{args.seconds:g} s sim time each (second half measured), load '
          f'{os.getloadavg()[0]:.1f}')
    for push, r in results.items():
        print(f'  push_to {"on " if push else "off"}: true yaw rate {r["yaw_rate"]:.3f} rad/s '
              f'({100 * (r["yaw_rate"] - W) / W:+.1f} % of the command), speed '
              f'{r["speed"]:.3f} m/s')


if __name__ == '__main__':
    main()
