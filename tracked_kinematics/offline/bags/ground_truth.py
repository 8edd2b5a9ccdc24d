"""Decode the ground-truth pose: Odometry, PoseStamped, PoseWithCovarianceStamped or tf."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader
from tracked_kinematics.core.integration import compose
from tracked_kinematics.offline.errors import BagError

from .columns import Columns, header_stamp, quaternion_yaw, sort_unique, strip_frame
from .opening import topic_connections
from .sources import GROUND_TRUTH_TYPES, GroundTruthSource


class GroundTruth:
    """Pose messages -> time, x, y, yaw of base_link."""

    def __init__(self, source: GroundTruthSource, path: Path, ref_ns: int):
        self.source = source
        self.path = path
        self.ref_ns = ref_ns
        self.columns = Columns(4)
        self.pairs: set[tuple[str, str]] = set()
        self._parent = strip_frame(source.parent_frame) or None

    def connections(self, reader: AnyReader):
        """Return the bag connections of the ground-truth topic (checked)."""
        return topic_connections(reader, self.path, self.source.topic, GROUND_TRUTH_TYPES,
                                 'ground truth')

    def add(self, conn, msg, receive_ns) -> None:
        msgtype = conn.msgtype
        if msgtype == 'tf2_msgs/msg/TFMessage':
            child = strip_frame(self.source.child_frame)
            for tf in msg.transforms:
                parent = strip_frame(tf.header.frame_id)
                self.pairs.add((parent, strip_frame(tf.child_frame_id)))
                if strip_frame(tf.child_frame_id) != child:
                    continue
                if self._parent is None:
                    self._parent = parent
                if parent == self._parent:
                    tr = tf.transform
                    self.columns.append((header_stamp(tf.header, receive_ns, self.ref_ns),
                                         tr.translation.x, tr.translation.y,
                                         quaternion_yaw(tr.rotation)))
            return
        pose = msg.pose.pose if msgtype in ('nav_msgs/msg/Odometry',
                                            'geometry_msgs/msg/PoseWithCovarianceStamped') \
            else msg.pose
        self.columns.append((header_stamp(msg.header, receive_ns, self.ref_ns), pose.position.x,
                             pose.position.y, quaternion_yaw(pose.orientation)))

    def poses(self):
        """Return the times (ns), x, y, yaw of base_link."""
        src = self.source
        child = strip_frame(src.child_frame)
        parents = sorted({p for p, c in self.pairs if c == child})
        pairs = ', '.join(f'{p} -> {c}' for p, c in sorted(self.pairs))
        if len(parents) > 1 and not src.parent_frame:
            raise BagError(
                f'{self.path}: several transforms to {child} on {src.topic} ({", ".join(parents)}'
                ' are parents); choose one with --ground-truth-parent-frame')
        data = self.columns.array
        data = sort_unique(data[np.all(np.isfinite(data), axis=1)])
        if len(data) < 2:
            what = f'transforms {src.parent_frame or "?"} -> {child}' if self.pairs else 'poses'
            raise BagError(f'{self.path}: fewer than two ground-truth {what} on {src.topic}'
                           + (f'; transforms present: {pairs}' if self.pairs else ''))
        t, x, y, yaw = data.T
        ox, oy, oyaw = src.offset
        if ox or oy or oyaw:
            # base_link = body (+) offset^-1
            back_x = -(math.cos(oyaw) * ox + math.sin(oyaw) * oy)
            back_y = -(-math.sin(oyaw) * ox + math.cos(oyaw) * oy)
            x, y, yaw = compose(x, y, yaw, back_x, back_y, -oyaw)
        return t, x, y, np.angle(np.exp(1j * yaw))
