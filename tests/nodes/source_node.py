#!/usr/bin/env python3
"""Stand-in node: publishes flip_msgs/MotorCommand on /motor_command (best effort, as the
contract says) at `rate` Hz, and ContactEvent on /contact_events (reliable, transient local)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import run  # noqa: E402
from flip_msgs.msg import ContactEvent, MotorCommand  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402

MOTORS = ["left_hip_roll", "left_hip_yaw", "left_hip_pitch", "left_knee", "left_foot",
          "right_hip_roll", "right_hip_yaw", "right_hip_pitch", "right_knee", "right_foot", "flywheel"]


class Source(Node):
    def __init__(self):
        super().__init__("source_node")
        rate = self.declare_parameter("rate", 20.0).value
        self.pub = self.create_publisher(MotorCommand, "/motor_command",
                                         QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
        self.ev = self.create_publisher(ContactEvent, "/contact_events",
                                        QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                                                   durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.step = 0
        e = ContactEvent(step=7, event=ContactEvent.TOUCH_DOWN, domain=ContactEvent.DOMAIN_LANDING)
        e.left_normal_force = 321.0
        self.ev.publish(e)
        self.create_timer(1.0 / rate, self.tick)

    def tick(self):
        m = MotorCommand(step=self.step, name=MOTORS, effort=[0.5 * i for i in range(11)],
                         compute_time_us=123.0)
        m.header.stamp.nanosec = 1000 * self.step
        self.pub.publish(m)
        self.step += 1


if __name__ == "__main__":
    sys.exit(run(Source))
