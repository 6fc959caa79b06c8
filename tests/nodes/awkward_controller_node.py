#!/usr/bin/env python3
"""Stand-in controller that answers sim_node's lockstep badly on purpose, then well: step 3's state
gets a /motor_command with 2 torques, its first re-send bytes that are no MotorCommand at all, its
second an answer to step 1 again (the simulator must send the state again after each: the stream
keeps one message), its third the right answer. Every other step gets zero torques at once."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import run  # noqa: E402
from flip_transport.lockstep import STREAM_QOS  # noqa: E402
from flip_msgs.msg import MotorCommand  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.node import Node  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

MOTORS = [f"motor_{i}" for i in range(11)]


class Awkward(Node):
    def __init__(self):
        super().__init__("tsc_node")
        self.pub = self.create_publisher(MotorCommand, "/motor_command", STREAM_QOS)
        self.create_subscription(JointState, "/joint_states", self.on_state, STREAM_QOS)
        self.create_subscription(Odometry, "/odom", lambda m: None, STREAM_QOS)   # sim_node waits for it
        self.seen = {}

    def on_state(self, js):
        k = (js.header.stamp.sec * 1_000_000_000 + js.header.stamp.nanosec) // 500_000
        n = self.seen[k] = self.seen.get(k, 0) + 1
        if k == 3 and n <= 3:
            self.get_logger().info(f"step 3, state {n}: " + ("2 torques", "garbage", "a stale answer")[n - 1])
            if n == 1:
                self.pub.publish(MotorCommand(header=js.header, step=3, name=MOTORS[:2], effort=[1.0, 2.0]))
            elif n == 2:
                self.pub.publish(b"\x00\x01\x00\x00 not a motor command")
            else:
                self.pub.publish(MotorCommand(header=js.header, step=1, name=MOTORS, effort=[0.0] * 11))
            return
        self.pub.publish(MotorCommand(header=js.header, step=k, name=MOTORS, effort=[0.0] * 11))


if __name__ == "__main__":
    sys.exit(run(Awkward))
