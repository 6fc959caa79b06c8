"""echo_controller: a trivial lockstep partner for sim_node (zero torques, one command per step).

Measures the transport alone: it answers each state with a MotorCommand for that step, doing no
work (or ``work_us`` of busy work, to stand in for a controller's tick).
"""
import sys
import time

import rclpy
from cassie_model.robot_params import MOTOR_NAMES
from flip_msgs.msg import MotorCommand
from flip_transport.lockstep import STREAM_QOS, SubscriptionSet, stamp_to_ns
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException
from sensor_msgs.msg import JointState

DT_NS = 500_000


def main(args=None):
    rclpy.init(args=args)
    node = rclpy.create_node('echo_controller')
    work_s = node.declare_parameter('work_us', 0.0).value * 1e-6
    subs = SubscriptionSet(node, [(JointState, '/joint_states', STREAM_QOS), (Odometry, '/odom', STREAM_QOS)])
    pub = node.create_publisher(MotorCommand, '/motor_command', STREAM_QOS)
    cmd = MotorCommand()
    cmd.name = list(MOTOR_NAMES)
    cmd.effort = [0.0] * len(MOTOR_NAMES)
    latest = {}
    try:
        while rclpy.ok():
            for topic, msg in subs.wait(1.0):
                latest[topic] = stamp_to_ns(msg.header.stamp)
            if subs.interrupted:
                break
            if len(latest) == 2 and latest['/joint_states'] == latest['/odom']:
                t0 = time.perf_counter()
                while time.perf_counter() - t0 < work_s:
                    pass
                cmd.step = latest['/joint_states'] // DT_NS
                pub.publish(cmd)
                latest.clear()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        subs.destroy()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
