#!/usr/bin/env python3
"""Stand-in for tsc_node: answers every /joint_states with a /motor_command (best effort)."""
import random
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import run  # noqa: E402
from flip_msgs.msg import MotorCommand  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import qos_profile_sensor_data  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402

MOTORS = ["left_hip_roll", "left_hip_yaw", "left_hip_pitch", "left_knee", "left_foot",
          "right_hip_roll", "right_hip_yaw", "right_hip_pitch", "right_knee", "right_foot", "flywheel"]


class FakeTsc(Node):
    def __init__(self):
        super().__init__("tsc_node")
        self.pub = self.create_publisher(MotorCommand, "/motor_command", qos_profile_sensor_data)
        self.create_subscription(JointState, "/joint_states", self.cb, qos_profile_sensor_data)
        from nav_msgs.msg import Odometry
        self.create_subscription(Odometry, "/odom", lambda m: None, qos_profile_sensor_data)
        self.create_subscription(String, "/robot_description_mjcf", lambda m: None,
                                 QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                            durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.step = 0

    def cb(self, js):
        t0 = time.perf_counter()
        fw = 0.0
        if "flywheel" in js.name:
            i = js.name.index("flywheel")
            fw = js.effort[i] if len(js.effort) > i else 0.0
        m = MotorCommand(header=js.header, step=self.step, name=MOTORS,
                         effort=[10.0 * random.random() for _ in range(10)] + [fw])
        self.step += 1
        m.compute_time_us = (time.perf_counter() - t0) * 1e6 + 100.0
        self.pub.publish(m)


if __name__ == "__main__":
    sys.exit(run(FakeTsc))
