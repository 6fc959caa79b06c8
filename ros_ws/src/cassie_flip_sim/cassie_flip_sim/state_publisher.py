"""state_publisher: the robot's transforms on /tf and /tf_static, as ROS's robot_state_publisher
gives them (the math, ROS-free, in ``link_transforms``).

- ``/robot_description`` (the URDF, latched) builds the model; its fixed joints go out once on
  ``/tf_static`` (latched);
- every ``/joint_states`` whose stamp is on the ``publish_rate`` grid of sim time (default 200 Hz,
  sim_node's ``/clock`` rate), together with the ``/odom`` of the same stamp, gives one ``/tf``
  message stamped with it: ``world`` -> ``pelvis`` (the ``/odom`` pose, its frame ids) and every
  moving URDF joint's parent link -> child link.

The simulator's per-step streams (2 kHz) are taken every ``POLL_S`` (not a wake-up per message)
by ``_rcl_io.take_on_grid``, which hands over only the grid's messages (serialized: read as
``cdr`` views), and /tf is written into a serialized template (:class:`TfTemplate`). The node
runs beside the lockstep, off its CPU (``lockstep.avoid_lockstep_cpu``; niced by ``flip``): it
queues (deep best-effort readers) instead of slowing the simulator. A stop (SIGINT, SIGTERM) ends the loop within ``POLL_S``, after which the
node publishes what it had already received (its own handlers, not rclpy's, which would shut the
context down first).
"""
from __future__ import annotations

import signal
import struct
import sys
import time

import numpy as np
import rclpy
from flip_transport import _rcl_io
from flip_transport.lockstep import (LATCHED_QOS, CdrCursor, MessageReader, SubscriptionSet, avoid_lockstep_cpu,
                                     joint_state_layout, odometry_layout, scheduling_note)
from flip_transport.node_stop import run_until_stopped
from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from .link_transforms import LinkTransforms

#: the simulator's streams, read beside the lockstep: ~0.5 s of 2 kHz states queue while it lags
DEEP_STREAM_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                             reliability=ReliabilityPolicy.BEST_EFFORT,
                             durability=DurabilityPolicy.VOLATILE)
#: tf2_ros' TransformBroadcaster and StaticTransformBroadcaster QoS
TF_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)
TF_STATIC_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: grid states kept while their partner (or the description) has not come, at most
MAX_PENDING = 400
#: wall time between two takes of what has queued: the node wakes at this rate, not per message
POLL_S = 0.01


def _ignore(_msg):
    return None


def transform(parent, child, pose, msg=None):
    """A TransformStamped (``msg`` filled in place when given) from an (x, y, z, qx, qy, qz, qw) pose."""
    msg = msg or TransformStamped()
    msg.header.frame_id, msg.child_frame_id = parent, child
    t, r = msg.transform.translation, msg.transform.rotation
    t.x, t.y, t.z, r.x, r.y, r.z, r.w = map(float, pose)
    return msg


class TfTemplate:
    """A TFMessage of fixed frames serialized once; each publish writes the stamp and the poses into
    its bytes (numpy) instead of building and serializing the message again. The byte offsets are
    found by serializing distinct marker values."""

    def __init__(self, frames):
        """``frames``: ``(parent, child)`` of every transform, in the order of the poses given."""
        n = len(frames)
        marks = 1.0e9 + np.arange(n * 7, dtype=float).reshape(n, 7) + 0.25
        msg = TFMessage(transforms=[transform(p, c, m) for (p, c), m in zip(frames, marks)])
        for i, m in enumerate(msg.transforms):
            m.header.stamp.sec, m.header.stamp.nanosec = 0x5EED0000 + i, 0x0BAD0000 + i
        self.buf = bytearray(serialize_message(msg))
        stamp_off = [self._find(struct.pack('<iI', 0x5EED0000 + i, 0x0BAD0000 + i)) for i in range(n)]
        pose_off = [self._find(marks[i].astype('<f8').tobytes()) for i in range(n)]
        self._u8 = np.frombuffer(self.buf, np.uint8)
        self._stamp_idx = np.asarray(stamp_off, int).reshape(n, 1) + np.arange(8)
        self._pose_idx = np.asarray(pose_off, int).reshape(n, 1) + np.arange(56)

    def _find(self, pattern):
        at = self.buf.find(pattern)
        if at < 0 or self.buf.find(pattern, at + 1) >= 0:
            raise ValueError('a marker of the TFMessage template is not unique')
        return at

    def fill(self, ns, poses):
        """The message's bytes with every stamp = ``ns`` and the ``(n, 7)`` poses."""
        stamp = np.frombuffer(struct.pack('<iI', ns // 1_000_000_000, ns % 1_000_000_000), np.uint8)
        self._u8[self._stamp_idx] = stamp
        self._u8[self._pose_idx] = np.ascontiguousarray(poses, '<f8').view(np.uint8).reshape(len(poses), 56)
        return bytes(self.buf)


def frame_ids(odom_raw):
    """``(header.frame_id, child_frame_id)`` of a serialized Odometry."""
    c = CdrCursor(odom_raw, 12)
    out = []
    for _ in range(2):
        n = c.uint()
        out.append(bytes(odom_raw[c.pos:c.pos + n - 1]).decode())
        c.pos += n
    return tuple(out)


class StatePublisher:
    """The node: subscriptions taken without an executor, two tf publishers."""

    def __init__(self):
        self.node = rclpy.create_node('state_publisher')
        rate = float(self.node.declare_parameter('publish_rate', 200.0).value)
        self.period_ns = int(round(1e9 / rate))
        self.subs = SubscriptionSet(self.node, [(String, '/robot_description', LATCHED_QOS)])
        # the per-step streams: taken by _rcl_io.take_on_grid (no executor calls their callbacks)
        self.streams = {topic: self.node.create_subscription(t, topic, _ignore, DEEP_STREAM_QOS, raw=True)
                        for t, topic in ((JointState, '/joint_states'), (Odometry, '/odom'))}
        self.pub_tf = self.node.create_publisher(TFMessage, '/tf', TF_QOS)
        self.pub_static = self.node.create_publisher(TFMessage, '/tf_static', TF_STATIC_QOS)
        self.model = None               # LinkTransforms of the URDF
        self.template = None            # (odom's frame ids, TfTemplate) of the /tf message
        self.read_js, self.read_odom = MessageReader(joint_state_layout), MessageReader(odometry_layout)
        self.pending = {'/joint_states': {}, '/odom': {}}    # grid stamp -> serialized message
        self.published = 0
        self.stop_requested = False

    def request_stop(self, signum=None, frame=None):  # noqa: ARG002 - signal handler signature
        self.stop_requested = True

    def _on_description(self, urdf):
        try:
            model = LinkTransforms(urdf)
        except Exception as e:  # noqa: BLE001 - a description that is no URDF: no tf, the node stays
            self.node.get_logger().error(f'/robot_description is not a URDF it can use: {e}')
            return
        self.model, self.template = model, None
        static = TFMessage(transforms=[transform(p, c, pose) for p, c, pose in model.fixed])
        self.pub_static.publish(static)
        self.node.get_logger().info(f'model from /robot_description: root {model.root}, '
                                    f'{len(model.edges)} moving and {len(model.fixed)} fixed joints')

    def _take(self):
        for _, msg in self.subs.take_all():
            self._on_description(msg.data)
        for topic, sub in self.streams.items():
            self.pending[topic].update(_rcl_io.take_on_grid(sub.handle.pointer, self.period_ns))

    def _publish(self, ns, js_raw, odom_raw):
        js, odom = self.read_js(js_raw), self.read_odom(odom_raw)
        self.model.set_positions(self.read_js.names[0], js['position'])
        frames = frame_ids(odom_raw)
        if self.template is None or self.template[0] != frames:
            self.template = (frames, TfTemplate([frames] + [(p, c) for p, c, _ in self.model.edges]))
        poses = np.concatenate([odom['pose'].reshape(1, 7), self.model.moving_poses()])
        self.pub_tf.publish(self.template[1].fill(ns, poses))
        self.published += 1

    def _flush(self):
        """Publish every stamp that has both messages (and a model); drop the oldest beyond MAX_PENDING."""
        js, odom = self.pending['/joint_states'], self.pending['/odom']
        if self.model is not None:
            for ns in sorted(set(js) & set(odom)):
                self._publish(ns, js.pop(ns), odom.pop(ns))
        for d in (js, odom):
            for ns in sorted(d)[:max(0, len(d) - MAX_PENDING)]:
                del d[ns]

    def run(self):
        cpu0 = time.process_time(), time.thread_time()
        while not self.stop_requested and rclpy.ok():
            time.sleep(POLL_S)
            self._take()
            self._flush()
        self._take()                          # what came before the stop
        self._flush()
        main = time.thread_time() - cpu0[1]
        self.node.get_logger().info(f'published /tf for {self.published} stamps; cpu s: main thread '
                                    f'{main:.2f}, other threads {time.process_time() - cpu0[0] - main:.2f}')
        return 0


def main(args=None):
    avoid_lockstep_cpu()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = StatePublisher()
    node.node.get_logger().info(scheduling_note())
    signal.signal(signal.SIGINT, node.request_stop)
    signal.signal(signal.SIGTERM, node.request_stop)

    def close():
        node.subs.destroy()
        for sub in node.streams.values():
            node.node.destroy_subscription(sub)
        node.node.destroy_node()
        rclpy.try_shutdown()
    return run_until_stopped(node.run, close)


if __name__ == '__main__':
    sys.exit(main())
