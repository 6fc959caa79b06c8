#!/usr/bin/env python3
"""Stand-in for planner_node: serves /request_flip, rejects impossible requests with a reason
(NaN, negative apex/distance/platform, unknown kind) and keeps serving; for an accepted one
publishes one FlipReference per domain on /fslip/reference (reliable, transient local)."""
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import run  # noqa: E402
from flip_msgs.msg import FlipReference  # noqa: E402
from flip_msgs.srv import RequestFlip  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402

G = 9.81


class FakePlanner(Node):
    def __init__(self):
        super().__init__("planner_node")
        self.declare_parameter("flywheel", "II")
        self.declare_parameter("platform_height", 0.0)
        self.flight_time = self.declare_parameter("flight_time", 0.6).value
        self.pub = self.create_publisher(FlipReference, "/fslip/reference",
                                         QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE,
                                                    durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.create_service(RequestFlip, "/request_flip", self.on_request)
        self.plan_id = 0
        self.now_sim = 0.0
        from rosgraph_msgs.msg import Clock
        from rclpy.qos import qos_profile_sensor_data
        self.create_subscription(Clock, "/clock", self.on_clock, qos_profile_sensor_data)

    def on_clock(self, msg):
        self.now_sim = msg.clock.sec + 1e-9 * msg.clock.nanosec

    def on_request(self, req, resp):
        t0 = time.perf_counter()
        vals = {"apex_height": req.apex_height, "forward_distance": req.forward_distance,
                "platform_height": req.platform_height}
        bad = [k for k, v in vals.items() if not math.isfinite(v)]
        if req.kind not in (RequestFlip.Request.BACKFLIP, RequestFlip.Request.FRONTFLIP, RequestFlip.Request.HOP):
            resp.accepted, resp.reason = False, f"unknown kind {req.kind}"
        elif bad:
            resp.accepted, resp.reason = False, f"{bad[0]} is not finite"
        elif min(vals.values()) < 0:
            k = min(vals, key=vals.get)
            resp.accepted, resp.reason = False, f"{k} must be >= 0"
        elif req.apex_height > 2.0:
            resp.accepted, resp.reason = False, "apex_height: liftoff velocity exceeds the leg's limit"
        else:
            self.plan_id += 1
            T = self.flight_time
            resp.accepted = True
            resp.plan_id = self.plan_id
            resp.flight_time = T
            resp.liftoff_zdot = G * T / 2
            resp.liftoff_xdot = req.forward_distance / T
            sign = {0: -1.0, 1: 1.0, 2: 0.0}[req.kind]
            resp.liftoff_pitch_rate = sign * 2 * math.pi / T
            resp.peak_flywheel_speed = 300.0
            resp.solve_time = time.perf_counter() - t0 + 0.05
            self.publish_reference(sign, T, resp.solve_time)
        return resp

    def publish_reference(self, sign, T, solve_time):
        start = self.now_sim + 0.2
        phases = [(FlipReference.DOMAIN_JUMPING, 0.0, 0.3), (FlipReference.DOMAIN_FLIGHT, 0.3, 0.3 + T),
                  (FlipReference.DOMAIN_LANDING, 0.3 + T, 0.8 + T)]
        for dom, a, b in phases:
            m = FlipReference(plan_id=self.plan_id, domain=dom)
            s = start + a
            m.start_time.sec = int(s)
            m.start_time.nanosec = int((s - int(s)) * 1e9)
            n = 11
            ts = [(b - a) * i / (n - 1) for i in range(n)]
            m.t = ts
            m.output_names = ["H_pitch", "L", "x_com", "phi_pitch"]
            vals = []
            for t in ts:
                tt = a + t
                phi = sign * 2 * math.pi * min(max((tt - 0.3) / T, 0.0), 1.0)
                vals += [sign * 30.0 if dom == FlipReference.DOMAIN_FLIGHT else sign * 30.0 * t / (b - a),
                         0.9, 0.0, phi]
            m.value = vals
            m.d_value = [0.0] * len(vals)
            m.dd_value = [0.0] * len(vals)
            m.parameter_names = ["T1"]
            m.parameter_values = [0.3]
            m.flight_time = T
            m.rotation_to_go = sign * 2 * math.pi
            m.solve_time = solve_time
            m.iterations = 12
            self.pub.publish(m)


if __name__ == "__main__":
    sys.exit(run(FakePlanner))
