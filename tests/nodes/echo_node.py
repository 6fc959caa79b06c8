#!/usr/bin/env python3
"""Stand-in node: relays flip_msgs/MotorCommand from `in_topic` to `out_topic`, setting
`compute_time_us` to the number of messages relayed so far (so a receiver can tell it went
through this process)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import run  # noqa: E402
from flip_msgs.msg import MotorCommand  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402


class Echo(Node):
    def __init__(self):
        super().__init__("echo_node")
        tin = self.declare_parameter("in_topic", "/motor_command").value
        tout = self.declare_parameter("out_topic", "/motor_command_echo").value
        be = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.pub = self.create_publisher(MotorCommand, tout, QoSProfile(depth=10))
        self.create_subscription(MotorCommand, tin, self.cb, be)
        self.n = 0

    def cb(self, msg):
        self.n += 1
        msg.compute_time_us = float(self.n)
        self.pub.publish(msg)


if __name__ == "__main__":
    sys.exit(run(Echo))
