"""A kinematic robot for node tests: cmd_vel in, joint_states and a true pose out."""

import math

from geometry_msgs.msg import Twist
from helpers.encoder_stream import joint_state, stamp
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool
from tracked_kinematics.core.kinematics import forward, IcrParams, inverse
from tracked_kinematics.core.plan.calibration_protocol import predict_step

RADIUS = 0.1
B = 0.42
# Martinez et al. (2005), Auriga-alpha on hard floor (docs/model.md, "Converting the papers'
# numbers").
AURIGA = IcrParams(B, 0.353, -0.425, 0.032, 1.0072, 1.0275)


class FakeRobot:
    """
    Integrates the ICR kinematics of ``truth`` under the commands of cmd_vel.

    The commands go through the ideal inverse kinematics (what an uncalibrated
    cmd_vel_translator does) to nominal track speeds, then through ``truth`` to the true
    motion. ``step(dt)`` advances and publishes one encoder sample and one pose, stamped
    with the node's clock.
    """

    def __init__(self, ros_context, executor, truth=AURIGA, name='fake_robot', namespace=''):
        self.node = Node(name, context=ros_context, namespace=namespace)
        executor.add_node(self.node)
        self.executor = executor
        self.truth = truth
        self.ideal = IcrParams.ideal(truth.track_width)
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.joints = self.node.create_publisher(type(joint_state(0.0, [0, 0])),
                                                 'joint_states', reliable)
        self.poses = self.node.create_publisher(Odometry, 'ground_truth/odom', reliable)
        self.deadman_pub = self.node.create_publisher(Bool, 'deadman', 10)
        self.cmds = []
        self.node.create_subscription(Twist, 'cmd_vel', self.cmds.append, reliable)
        self.angle = [0.0, 0.0]
        self.pose = [0.0, 0.0, 0.0]
        self.max_distance = 0.0
        self._last = None

    def tick(self, period=0.02, **kwargs):
        """Step by the time since the last step once ``period`` s have passed; return if so."""
        now = self.now()
        if self._last is None:
            self._last = now
        if now - self._last < period:
            return False
        self.step(min(now - self._last, 0.2), **kwargs)
        self._last = now
        return True

    def now(self):
        return self.node.get_clock().now().nanoseconds * 1e-9

    def deadman(self, held=True):
        self.deadman_pub.publish(Bool(data=held))

    def step(self, dt, publish_pose=True, publish_encoders=True):
        """Move by the latest command for ``dt`` s; publish the sensors."""
        cmd = self.cmds[-1] if self.cmds else Twist()
        left, right = inverse(cmd.linear.x, cmd.angular.z, self.ideal)
        left, right = float(left), float(right)
        v_x, v_y, w = (float(c) for c in forward(self.truth.scale_left * left,
                                                 self.truth.scale_right * right, self.truth))
        # The body twist (with its lateral slip) held for dt, exactly along the arc.
        x, y, yaw = predict_step((0.0, 0.0, 0.0), math.hypot(v_x, v_y), w, dt, 1)
        slip = math.atan2(v_y, v_x) if (v_x or v_y) else 0.0
        c0, s0 = math.cos(self.pose[2] + slip), math.sin(self.pose[2] + slip)
        dx, dy = float(x[0]), float(y[0])
        self.pose = [self.pose[0] + c0 * dx - s0 * dy, self.pose[1] + s0 * dx + c0 * dy,
                     self.pose[2] + w * dt]
        self.angle[0] += left * dt / RADIUS
        self.angle[1] += right * dt / RADIUS
        self.max_distance = max(self.max_distance, math.hypot(*self.pose[:2]))
        t = self.now()
        if publish_encoders:
            self.joints.publish(joint_state(t, list(self.angle)))
        if publish_pose:
            msg = Odometry()
            msg.header.stamp = stamp(t)
            msg.header.frame_id = 'odom'
            msg.child_frame_id = 'base_link'
            msg.pose.pose.position.x, msg.pose.pose.position.y = self.pose[0], self.pose[1]
            msg.pose.pose.orientation.z = math.sin(0.5 * self.pose[2])
            msg.pose.pose.orientation.w = math.cos(0.5 * self.pose[2])
            self.poses.publish(msg)
