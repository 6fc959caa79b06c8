#!/usr/bin/env python3
"""Stand-in for sim_node (no physics): publishes /clock, /odom, /joint_states, /contact_events,
/robot_description (a one-link URDF) and /robot_description_mjcf with the contract's QoS, plays a
scripted flip when a FlipReference arrives (rotation = its rotation_to_go, flight = its
flight_time) and exits by itself once sim time reaches the `duration` parameter (re-read every
step, so it can be set at run time).
Like sim_node it holds the first step until /joint_states and /odom have `min_subscribers`
subscribers (+1 with controller:=tsc) and /clock has `min_subscribers`, and with `hold` until
/sim/release is called.
`outcome:=fall` ends the flip tilted 90 deg, low. Sim time advances `rate` x wall time."""
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import run  # noqa: E402
from flip_msgs.msg import ContactEvent, FlipReference, MotorCommand  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

G = 9.81
Z0 = 1.0


def tl(depth):
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


def be():
    return QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)


class FakeSim(Node):
    def __init__(self):
        super().__init__("sim_node")
        for k, v in [("mode", "lockstep"), ("controller", "tsc"), ("flywheel", "II"), ("scenario", "flat"),
                     ("platform_height", 0.0), ("ground_offset", 0.0), ("video_path", ""),
                     ("outcome", "land"), ("distance", 0.5)]:
            self.declare_parameter(k, v)
        self.declare_parameter("duration", 0.0)
        self.min_subscribers = self.declare_parameter("min_subscribers", 0).value
        self.released = not self.declare_parameter("hold", False).value
        self.create_service(Trigger, "/sim/release", self.on_release)
        self.started = False
        self.rate = self.declare_parameter("rate", 2.0).value
        self.dt = 0.005
        self.p_clock = self.create_publisher(Clock, "/clock", be())
        self.p_odom = self.create_publisher(Odometry, "/odom", be())
        self.p_js = self.create_publisher(JointState, "/joint_states", be())
        self.p_ev = self.create_publisher(ContactEvent, "/contact_events", tl(10))
        self.p_desc = self.create_publisher(String, "/robot_description", tl(1))
        self.p_desc.publish(String(data="<robot name='fake_cassie'><link name='pelvis'/></robot>"))
        self.p_mjcf = self.create_publisher(String, "/robot_description_mjcf", tl(1))
        self.p_mjcf.publish(String(data="<mujoco model='fake_cassie'/>"))
        self.create_subscription(FlipReference, "/fslip/reference", self.on_ref, tl(5))
        self.create_subscription(MotorCommand, "/motor_command", lambda m: None, qos_profile_sensor_data)
        self.t = 0.0
        self.step = 0
        self.plan = None
        self.prev = None
        self.events_sent = set()
        self.finished = False
        self.create_timer(self.dt / self.rate, self.tick)

    def on_release(self, request, response):
        self.released = response.success = True
        return response

    def on_ref(self, m):
        if m.domain == FlipReference.DOMAIN_JUMPING and self.plan is None:
            s = m.start_time.sec + 1e-9 * m.start_time.nanosec
            self.plan = {"t_start": max(s, self.t), "T": m.flight_time, "rot": m.rotation_to_go}

    def pose(self, t):
        """x, z, theta (pitch about +y) of the pelvis at sim time t."""
        if self.plan is None or t < self.plan["t_start"]:
            return 0.0, Z0, 0.0
        p = self.plan
        fall = self.get_parameter("outcome").value == "fall"
        d = self.get_parameter("distance").value
        t_lo = p["t_start"] + 0.3
        t_td = t_lo + p["T"]
        if t < t_lo:
            return 0.0, Z0 - 0.1 * math.sin(math.pi * (t - p["t_start"]) / 0.3), 0.0
        if t < t_td:
            tau = t - t_lo
            vz = G * p["T"] / 2
            s = tau / p["T"]
            return d * s, Z0 + vz * tau - G * tau * tau / 2, p["rot"] * (3 * s * s - 2 * s * s * s)
        s = min((t - t_td) / 0.4, 1.0)
        zf, extra = (0.25, math.copysign(math.pi / 2, p["rot"] or 1.0)) if fall else (0.9, 0.0)
        w = 0.5 - 0.5 * math.cos(math.pi * s)
        return d, Z0 + (zf - Z0) * w, p["rot"] + extra * w

    def stamp(self, msg_header):
        msg_header.stamp.sec = int(self.t)
        msg_header.stamp.nanosec = int(round((self.t - int(self.t)) * 1e9)) % 1000000000

    def tick(self):
        if not self.started:   # like sim_node: hold the first step until the subscribers are there
            ctl = self.get_parameter("controller").value == "tsc"
            need = self.min_subscribers + (1 if ctl else 0)
            self.started = self.released and (self.p_js.get_subscription_count() >= need and
                            self.p_odom.get_subscription_count() >= need and
                            self.p_clock.get_subscription_count() >= self.min_subscribers)
            if not self.started:
                return
        dur = self.get_parameter("duration").value
        if dur > 0 and self.t >= dur - 1e-9:
            self.finished = True
            return
        x, z, th = self.pose(self.t)
        if self.prev is None:
            vx = vz = w = 0.0
        else:
            vx, vz, w = ((x - self.prev[0]) / self.dt, (z - self.prev[1]) / self.dt, (th - self.prev[2]) / self.dt)
        self.prev = (x, z, th)
        c = Clock()
        c.clock.sec = int(self.t)
        c.clock.nanosec = int(round((self.t - int(self.t)) * 1e9)) % 1000000000
        self.p_clock.publish(c)
        o = Odometry()
        self.stamp(o.header)
        o.header.frame_id, o.child_frame_id = "world", "pelvis"
        o.pose.pose.position.x, o.pose.pose.position.z = x, z
        o.pose.pose.orientation.y, o.pose.pose.orientation.w = math.sin(th / 2), math.cos(th / 2)
        # twist in the pelvis frame: R_y(th)^T v_world
        o.twist.twist.linear.x = math.cos(th) * vx - math.sin(th) * vz
        o.twist.twist.linear.z = math.sin(th) * vx + math.cos(th) * vz
        o.twist.twist.angular.y = w
        self.p_odom.publish(o)
        js = JointState()
        self.stamp(js.header)
        js.name = ["left_knee", "right_knee", "flywheel"]
        js.position = [-1.2, -1.2, 0.0]
        flying = self.plan is not None and abs(w) > 1e-6
        js.velocity = [0.0, 0.0, -w * 20.0 if flying else 0.0]
        js.effort = [5.0, 5.0, 3.0 if flying else 0.0]
        self.p_js.publish(js)
        if self.plan is not None:
            t_lo = self.plan["t_start"] + 0.3
            for key, when, ev, dom in (("lo", t_lo, ContactEvent.LIFT_OFF, ContactEvent.DOMAIN_FLIGHT),
                                       ("td", t_lo + self.plan["T"], ContactEvent.TOUCH_DOWN,
                                        ContactEvent.DOMAIN_LANDING)):
                if key not in self.events_sent and self.t >= when:
                    self.events_sent.add(key)
                    e = ContactEvent(step=self.step, event=ev, domain=dom)
                    self.stamp(e.header)
                    e.pelvis_pose = o.pose.pose
                    e.com_position.x, e.com_position.z = x, z
                    e.centroidal_pitch_momentum = 30.0 * math.copysign(1.0, self.plan["rot"] or 1.0)
                    e.left_normal_force = e.right_normal_force = 0.0 if ev == ContactEvent.LIFT_OFF else 400.0
                    self.p_ev.publish(e)
        self.t += self.dt
        self.step += 1


if __name__ == "__main__":
    sys.exit(run(FakeSim))
