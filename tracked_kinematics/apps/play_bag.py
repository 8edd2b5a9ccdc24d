"""
play_bag (console script): a bag's topics onto live ROS topics at their recorded pace.

The venv's ``ros2 bag play``: :class:`~tracked_kinematics.offline.bags.playback.BagPlayback`
reads the recorded messages (rosbags), :func:`tracked_kinematics.ros.bag_player.play`
publishes them (rclpy). Exit status: 0 played to the end or stopped by SIGINT / SIGTERM (at
any instant); 2 bad input (options, a missing, corrupt or ROS 1 bag, a topic not in it,
nothing playable). Reference: docs/tools/play_bag.md.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import rclpy
from rclpy.signals import SignalHandlerOptions
from tracked_kinematics.offline.bags.playback import BagPlayback
from tracked_kinematics.offline.cli.common import ArgumentParser, bounded, HelpFormatter
from tracked_kinematics.offline.errors import BagError
from tracked_kinematics.ros.bag_player import BagPlayer, play, STOP_POLL
from tracked_kinematics.ros.main import StopRequest

PROG = 'play_bag'
EXIT_INPUT = 2


def build_parser() -> argparse.ArgumentParser:
    """Argument parser of ``play_bag``."""
    parser = ArgumentParser(
        prog=PROG, formatter_class=HelpFormatter,
        usage=f'{PROG} BAG [options] [--ros-args ...]',
        description='Publish the topics of a rosbag2 bag (sqlite3 or mcap) at their recorded '
                    'pace, as `ros2 bag play` does, from a venv (rosbags + rclpy).',
        epilog='examples:\n'
               '  play_bag ../shared/realdata/warthog_grass_2024-07-29_14h04\n'
               '  play_bag my_run --topics /joint_states /imu/data --rate 2\n'
               '  play_bag my_run --clock --start 30 --duration 60 --loop\n'
               '  play_bag my_run --ros-args -r /imu/data:=/imu')
    parser.add_argument('bag', metavar='BAG', help='rosbag2 directory')
    parser.add_argument('--topics', nargs='+', metavar='TOPIC', default=None,
                        help='topics to play (default: every topic whose type is installed)')
    parser.add_argument('--rate', type=bounded(0.01, 100.0), default=1.0,
                        help='bag seconds per second (2: twice as fast), 0.01-100')
    parser.add_argument('--clock', type=bounded(1.0, 1000.0, 'Hz'), nargs='?', const=100.0,
                        default=None, metavar='HZ',
                        help='publish the bag time on /clock (HZ while no message is due, '
                             '100 Hz when not given); run the nodes with use_sim_time')
    parser.add_argument('--start', type=bounded(0.0, 1e9, 's'), default=0.0,
                        help='begin this many seconds after the bag start')
    parser.add_argument('--duration', type=bounded(0.001, 1e9, 's'), default=None,
                        help='play this many seconds of the bag (default: to the end)')
    parser.add_argument('--loop', action='store_true',
                        help='start over at the end, until stopped (with --clock the time '
                             'goes back at each start)')
    parser.add_argument('--delay', type=bounded(0.0, 60.0, 's'), default=1.0,
                        help='wait this long after creating the publishers, so that the '
                             'subscribers discover them before the first message')
    parser.add_argument('--wait-for', nargs='+', metavar='TOPIC', default=None,
                        help='before the first message, wait (until stopped) for a subscriber '
                             'on each of these played topics')
    parser.add_argument('--ros-args', nargs=argparse.REMAINDER, default=None, metavar='ARG',
                        help='the rest goes to rcl for the player node (e.g. -r FROM:=TO '
                             'remaps a topic)')
    return parser


def _topic_table(playback: BagPlayback, player: BagPlayer) -> str:
    width = max(len(topic.name) for topic in playback.topics)
    lines = []
    for topic in playback.topics:
        played = player.published_as(topic.name)
        lines.append(f'{topic.name:<{width}}  {topic.msgtype:<40} {topic.count:>8,}'
                     + ('  (not played)' if not played else
                        f'  -> {played}' if played != topic.name else ''))
    return '\n'.join(lines)


def main(argv=None) -> int:
    """Run play_bag (console script ``play_bag``); return its exit status."""
    args = build_parser().parse_args(sys.argv[1:] if argv is None else list(argv))
    ros_args = [] if args.ros_args is None else ['--ros-args', *args.ros_args]
    stop = StopRequest()
    with stop.installed():
        try:
            playback = BagPlayback(args.bag, args.topics or (), args.start,
                                   math.inf if args.duration is None else args.duration)
        except BagError as err:
            print(f'{PROG}: error: {err}', file=sys.stderr)
            return EXIT_INPUT
        if stop.requested:
            return 0
        return _play(playback, args, ros_args, stop)


def _play(playback: BagPlayback, args, ros_args, stop: StopRequest) -> int:
    rclpy.init(args=[PROG, *ros_args], signal_handler_options=SignalHandlerOptions.NO)
    node = None
    try:
        node = rclpy.create_node(PROG)

        def warn(text):
            print(f'{PROG}: warning: {text}', file=sys.stderr)
        player = BagPlayer(node, [(t.name, t.msgtype) for t in playback.topics],
                           clock=args.clock is not None, warn=warn)
        if not player.topics:
            print(f'{PROG}: error: nothing to play in {playback.path}: no topic has an '
                  'installed message type', file=sys.stderr)
            return EXIT_INPUT
        window = (playback.end_ns if math.isfinite(playback.end_ns) else None)
        print(f'{playback.path}: {playback.message_count:,} messages from '
              f'{(playback.start_ns - playback.bag_start_ns) * 1e-9:g} s'
              + (f' to {(window - playback.bag_start_ns) * 1e-9:g} s' if window else '')
              + f' at rate {args.rate:g}' + (', /clock' if args.clock else '')
              + (', looped' if args.loop else ''))
        print(_topic_table(playback, player), flush=True)
        if args.wait_for:
            unknown = [topic for topic in args.wait_for if topic not in player.topics]
            if unknown:
                print(f'{PROG}: error: --wait-for {", ".join(unknown)}: not a played topic',
                      file=sys.stderr)
                return EXIT_INPUT
            while not stop.requested and not all(
                    player.subscribers(topic) for topic in args.wait_for):
                time.sleep(STOP_POLL)
        try:
            stats = play(player, playback.messages, playback.start_ns, args.rate,
                         lambda: stop.requested, loop=args.loop, delay=args.delay,
                         clock_period=1.0 / (args.clock or 100.0))
        except BagError as err:
            print(f'{PROG}: error: {err}', file=sys.stderr)
            return EXIT_INPUT
        print(f'played {stats.messages:,} messages'
              + (f' in {stats.loops} loops' if stats.loops > 1 else '')
              + (' (stopped)' if stats.stopped else ''), flush=True)
        return 0
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
