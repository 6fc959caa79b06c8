"""planner_node: the FSLIP planner as a ROS 2 node (thin adapter around ``fslip_planner.plan``).

- ``/request_flip`` (flip_msgs/RequestFlip): validate → read the measured pelvis state (the newest
  ``/odom``) → refuse unless the robot stands → solve the jumping optimisation → read the robot again
  and anchor the plan where it stands then (``FlipSession.reanchored``) → publish the JUMPING
  reference; an impossible or malformed request gets ``accepted=false`` and a reason.
- ``/contact_events`` LIFT_OFF → flight plan (momentum transmission) from the measured state;
  TOUCH_DOWN → landing optimisation from the measured touch-down state (before the impact: the
  controller scales the plan's momentum to what the impact leaves, ``landing_impact_time``).
Every reference goes out on ``/fslip/reference`` with its solve time, and then, for a viewer, as
geometry in the world frame (``plan_geometry``): its COM path on ``/fslip/com_path`` (nav_msgs/Path)
and the foot targets of the flip so far on ``/fslip/targets`` (visualization_msgs/MarkerArray: a
DELETEALL, then a sphere per target), both latched (transient local, depth 1).
"""
from __future__ import annotations

import math
import sys
import time

import numpy as np
import rclpy
from cassie_model.description import flywheel_inertial
from cassie_model.model import export_mjcf
from cassie_model.robot_params import FOOT_RADIUS
from flip_msgs.msg import ContactEvent, FlipReference
from flip_msgs.srv import RequestFlip
from flip_transport.lockstep import LATCHED_QOS, STREAM_QOS, SubscriptionSet, ns_to_stamp, stamp_to_ns
from flip_transport.node_stop import run_until_stopped
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry, Path
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from visualization_msgs.msg import Marker, MarkerArray

from .feasibility import com_of_standing
from .landing import landing_attempt_note
from .landing_predictions import PredictionBudget
from .plan import FlipSession, InfeasibleRequest, MeasuredState, PelvisState
from .pitch_turns import PitchTurns
from .plan_geometry import reference_geometry

KINDS = {RequestFlip.Request.BACKFLIP: 'backflip', RequestFlip.Request.FRONTFLIP: 'frontflip',
         RequestFlip.Request.HOP: 'hop'}
#: sim-time lead given to the controller between publishing a jumping plan and its start
START_LEAD_S = 0.25
#: wall seconds a request waits for the simulator's /odom (the measured state a plan starts from)
STATE_TIMEOUT_S = 2.0
#: /fslip/com_path and /fslip/targets: the newest, to a viewer that comes later too
VIEW_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)
DOMAIN_NAMES = {FlipReference.DOMAIN_JUMPING: 'jumping', FlipReference.DOMAIN_FLIGHT: 'flight',
                FlipReference.DOMAIN_LANDING: 'landing'}
#: marker colours (r, g, b) of the foot targets: where a stance foot is, where a flight touches down
TARGET_COLORS = {'stance': (0.1, 0.7, 0.2), 'touchdown': (1.0, 0.45, 0.0)}
TARGET_DIAMETER = 0.06


def measured_state(ev):
    """The floating-base state carried by a ContactEvent, as the planner's MeasuredState."""
    q = ev.pelvis_pose.orientation
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (q.w * q.y - q.z * q.x))))
    return MeasuredState(
        t=stamp_to_ns(ev.header.stamp) * 1e-9,
        com=np.array([ev.com_position.x, ev.com_position.y, ev.com_position.z]),
        com_velocity=np.array([ev.com_velocity.x, ev.com_velocity.y, ev.com_velocity.z]),
        pitch_momentum=ev.centroidal_pitch_momentum,
        pelvis_pitch=pitch,
        pelvis_pitch_rate=ev.pelvis_twist.angular.y,
        support_center=np.array([ev.support_center.x, ev.support_center.y, ev.support_center.z]))


def geometry_of(msg, **anchor):
    """plan_geometry.reference_geometry of a FlipReference message's fields; ``anchor``: its
    com, com_velocity, foot_z, landing_foot_z."""
    return reference_geometry(msg.domain, stamp_to_ns(msg.start_time) * 1e-9, msg.t, list(msg.output_names),
                              np.asarray(msg.value, float), dict(zip(msg.parameter_names, msg.parameter_values)),
                              flight_time=msg.flight_time, liftoff_xdot=msg.liftoff_xdot,
                              liftoff_zdot=msg.liftoff_zdot, **anchor)


def path_message(geo):
    """nav_msgs/Path (frame world) of a PlanGeometry, each pose stamped with its sim time."""
    path = Path()
    path.header.frame_id = 'world'
    ns_to_stamp(int(round(geo.t[0] * 1e9)), path.header.stamp)
    for t, p, q in zip(geo.t, geo.com, geo.quaternions()):
        ps = PoseStamped()
        ps.header.frame_id = 'world'
        ns_to_stamp(int(round(t * 1e9)), ps.header.stamp)
        ps.pose.position.x, ps.pose.position.y, ps.pose.position.z = map(float, p)
        o = ps.pose.orientation
        o.x, o.y, o.z, o.w = map(float, q)
        path.poses.append(ps)
    return path


def target_markers(geo, plan_id, domain):
    """A sphere Marker (frame world, namespace ``<domain>/<label>``, id = plan id) per foot target."""
    out = []
    for label, point in geo.feet:
        m = Marker()
        m.header.frame_id = 'world'
        ns_to_stamp(int(round(geo.t[0] * 1e9)), m.header.stamp)
        m.ns = f'{DOMAIN_NAMES.get(domain, domain)}/{label}'
        m.id = int(plan_id)
        m.type, m.action = Marker.SPHERE, Marker.ADD
        m.pose.position.x, m.pose.position.y, m.pose.position.z = map(float, point)
        m.pose.orientation.w = 1.0
        m.scale.x = m.scale.y = m.scale.z = TARGET_DIAMETER
        m.color.r, m.color.g, m.color.b = TARGET_COLORS.get(label, (0.5, 0.5, 0.5))
        m.color.a = 1.0
        out.append(m)
    return out


def pelvis_state(odom):
    """The pelvis of an /odom message as the planner's PelvisState."""
    p, q = odom.pose.pose.position, odom.pose.pose.orientation
    v, w = odom.twist.twist.linear, odom.twist.twist.angular
    return PelvisState(t=stamp_to_ns(odom.header.stamp) * 1e-9, position=np.array([p.x, p.y, p.z]),
                       orientation=np.array([q.x, q.y, q.z, q.w]), linear_velocity=np.array([v.x, v.y, v.z]),
                       angular_velocity=np.array([w.x, w.y, w.z]))


class PlannerNode:
    def __init__(self):
        self.node = rclpy.create_node('planner_node')
        n = self.node
        self.flywheel = n.declare_parameter('flywheel', 'I').value
        self.platform_height = float(n.declare_parameter('platform_height', 0.0).value)
        self.motor_speed_scale = float(n.declare_parameter('motor_speed_scale', 1.0).value)
        # flywheel motor's torque limit, N·m (0 = the flywheel's own), as in the simulator
        self.flywheel_torque = float(n.declare_parameter('flywheel_torque', 0.0).value)
        # false: a design study's jumps whose planned flight needs more flywheel torque than the motor
        # gives are not refused (FlipSession's flight_check)
        self.flight_check = bool(n.declare_parameter('flight_check', True).value)
        # true: the knee torque of the tangential foot force is planned too (FlipSession's knee_tangential)
        self.knee_tangential = bool(n.declare_parameter('knee_tangential', False).value)
        self.pub = n.create_publisher(FlipReference, '/fslip/reference', LATCHED_QOS)
        self.pub_path = n.create_publisher(Path, '/fslip/com_path', VIEW_QOS)
        self.pub_targets = n.create_publisher(MarkerArray, '/fslip/targets', VIEW_QOS)
        self._targets = {}              # the foot-target markers of the flip under way, by (ns, id)
        self._warm_up()
        n.create_service(RequestFlip, '/request_flip', self._on_request)
        self._events = n.create_subscription(ContactEvent, '/contact_events', self._on_event, LATCHED_QOS)
        self._waiting = []              # contact events taken while the landing predictions were solved
        # the simulated robot's description: a flywheel other than the one planned for is refused
        self.sim_mjcf = None
        self._own_flywheel = flywheel_inertial(export_mjcf(self.flywheel))
        n.create_subscription(String, '/robot_description_mjcf', self._on_description, LATCHED_QOS)
        # The newest /clock is read on demand from a node no executor spins (no 2 kHz callbacks).
        self._clock_node = rclpy.create_node('planner_clock')
        self._clock = SubscriptionSet(self._clock_node, [(Clock, '/clock', STREAM_QOS)])
        self.session = None
        self.plan_id = 0
        # the somersaults turned so far, added to each flight plan (a second flip's flight plan turned
        # the body the wrong way without it; fslip_planner.pitch_turns)
        self.turns = PitchTurns()

    def _sim_now(self):
        got = self._clock.take_all()
        if got:
            self._last_clock = stamp_to_ns(got[-1][1].clock) * 1e-9
        return getattr(self, '_last_clock', 0.0)

    def _measured_pelvis(self):
        """The newest /odom as a PelvisState, with the flywheel's speed from /joint_states, or None if
        no /odom came within STATE_TIMEOUT_S (the flywheel unmeasured if no /joint_states did). The
        subscriptions live for this request only: standing ones would take 2,000 messages a second
        each here and add readers to every step of the simulator."""
        odom = self._clock_node.create_subscription(Odometry, '/odom', lambda _m: None, STREAM_QOS)
        joints = self._clock_node.create_subscription(JointState, '/joint_states', lambda _m: None, STREAM_QOS)
        try:
            deadline = time.monotonic() + STATE_TIMEOUT_S
            pelvis = js = None
            while time.monotonic() < deadline and (pelvis is None or js is None):
                got = odom.handle.take_message(odom.msg_type, False) if pelvis is None else None
                if got is not None:
                    pelvis = pelvis_state(got[0])
                got = joints.handle.take_message(joints.msg_type, False) if js is None else None
                if got is not None:
                    js = got[0]
                time.sleep(0.002)
            if pelvis is not None and js is not None and 'flywheel' in js.name:
                pelvis.flywheel_speed = float(js.velocity[list(js.name).index('flywheel')])
            return pelvis
        finally:
            self._clock_node.destroy_subscription(odom)
            self._clock_node.destroy_subscription(joints)

    def _publish(self, ref, start_time):
        msg = FlipReference()
        msg.plan_id = self.plan_id
        msg.domain = ref.domain
        ns_to_stamp(int(round(start_time * 1e9)), msg.start_time)
        ns_to_stamp(int(round(start_time * 1e9)), msg.header.stamp)
        msg.t = [float(x) for x in ref.t]
        msg.output_names = list(ref.names)
        msg.value = np.asarray(ref.value, float).ravel().tolist()
        msg.d_value = np.asarray(ref.d_value, float).ravel().tolist()
        msg.dd_value = np.asarray(ref.dd_value, float).ravel().tolist()
        msg.parameter_names = list(ref.parameters)
        msg.parameter_values = [float(v) for v in ref.parameters.values()]
        for field in ('liftoff_zdot', 'liftoff_xdot', 'flight_time', 'rotation_to_go',
                      'peak_flywheel_speed', 'solve_time'):
            setattr(msg, field, float(ref.figures.get(field, 0.0)))
        msg.iterations = int(ref.figures.get('iterations', 0))
        self.pub.publish(msg)
        self.node.get_logger().info(
            f'plan {self.plan_id}: domain {ref.domain} published, start t={start_time:.4f} s, '
            f'solve {1e3 * ref.figures.get("solve_time", 0.0):.1f} ms')
        return msg

    def _publish_geometry(self, msg, **anchor):
        """/fslip/com_path and /fslip/targets of a reference just published (module doc)."""
        try:
            geo = geometry_of(msg, **anchor)
        except ValueError as e:
            self.node.get_logger().warn(f'plan {msg.plan_id}: domain {msg.domain}: no geometry to show: {e}')
            return
        if msg.domain == FlipReference.DOMAIN_JUMPING:
            self._targets = {}
        # a second flight or landing of the flip (a rebound) replaces the first's targets
        self._targets.update({(m.ns, m.id): m for m in target_markers(geo, msg.plan_id, msg.domain)})
        self.pub_path.publish(path_message(geo))
        clear = Marker(action=Marker.DELETEALL)
        clear.header.frame_id = 'world'
        self.pub_targets.publish(MarkerArray(markers=[clear] + list(self._targets.values())))

    def _warm_up(self):
        """One backflip planned from the standing state before the service is offered: the robot's
        figures and the optimisation's first build are made now, not in the first request (measured
        in a fresh process: 0.92 s for the first session and plan, 0.41 s for the next), during which
        a free-running simulator goes on and the plan starts later in sim time."""
        t0 = time.perf_counter()
        try:
            FlipSession('backflip', platform_height=self.platform_height, flywheel=self.flywheel,
                        motor_speed_scale=self.motor_speed_scale, flywheel_torque=self.flywheel_torque,
                        flight_check=self.flight_check, knee_tangential=self.knee_tangential).jumping_reference()
        except (InfeasibleRequest, ValueError) as e:      # a robot that cannot backflip still serves
            self.node.get_logger().info(f'warm-up plan refused ({e})')
        self.node.get_logger().info(f'warmed up in {time.perf_counter() - t0:.2f} s')

    def _on_description(self, msg):
        self.sim_mjcf = msg.data

    def robot_mismatch(self) -> str | None:
        """Why the simulated robot (its /robot_description_mjcf) cannot be planned for, or None: its
        flywheel is not the planner's (the FSLIP's K, D, I regressions are for the named flywheels)."""
        if self.sim_mjcf is None:
            return None
        try:
            sim = flywheel_inertial(self.sim_mjcf)
        except ValueError as e:
            return f'robot_mismatch: /robot_description_mjcf unreadable: {e}'
        own = self._own_flywheel
        if sim is not None and own is not None and np.allclose(sim[0], own[0]) and np.allclose(sim[1], own[1]):
            return None
        fmt = (lambda f: 'none' if f is None else f'{f[0]:g} kg, pitch inertia {f[1][1]:g} kg m^2')
        return (f'robot_mismatch: the simulated flywheel ({fmt(sim)}) is not flywheel {self.flywheel} ({fmt(own)}), '
                'the one this planner models: give planner_node the flywheel the simulator has (I, II or III)')

    def _on_request(self, req, res):
        res.accepted = False
        kind = KINDS.get(req.kind)
        if kind is None:
            res.reason = f'unknown kind {req.kind}: expected 0 (backflip), 1 (frontflip) or 2 (hop)'
            return res
        mismatch = self.robot_mismatch()
        if mismatch is not None:
            res.reason = mismatch
            self.node.get_logger().warn(f'request refused: {mismatch}')
            return res
        if self.session is not None and not self.session.finished(self._sim_now()):
            res.reason = f'a flip (plan {self.plan_id}) is under way: wait until it has landed'
            return res
        try:
            session = FlipSession(kind, apex_height=req.apex_height or None,
                                  forward_distance=req.forward_distance,
                                  platform_height=req.platform_height or self.platform_height,
                                  flywheel=self.flywheel, motor_speed_scale=self.motor_speed_scale,
                                  flywheel_torque=self.flywheel_torque, flight_check=self.flight_check,
                                  knee_tangential=self.knee_tangential)
            # every plan starts from the measured state: refused unless the robot stands
            state = self._measured_pelvis()
            if state is None:
                raise InfeasibleRequest(f'no_state: no /odom from the simulator within {STATE_TIMEOUT_S:g} s: '
                                        'the state of the robot is unknown', 'no_state')
            ref = session.jumping_reference(state)
            # the solve took a while and the robot may have moved: the plan starts where it stands now
            newer = self._measured_pelvis()
            if newer is not None:
                ref, state = session.reanchored(newer), newer
        except (InfeasibleRequest, ValueError) as e:
            res.reason = str(e)
            self.node.get_logger().warn(f'request refused: {e}')
            return res
        self.plan_id += 1
        self.session = session
        start = self._sim_now() + START_LEAD_S
        session.started(start)
        msg = self._publish(ref, start)
        ground = session.platform + FOOT_RADIUS           # the contact spheres' centres (the FSLIP's foot)
        self._publish_geometry(msg, com=com_of_standing(state, session.robot), foot_z=ground,
                               landing_foot_z=FOOT_RADIUS)
        f = ref.figures
        res.accepted = True
        res.plan_id = self.plan_id
        res.liftoff_zdot = float(f.get('liftoff_zdot', 0.0))
        res.liftoff_xdot = float(f.get('liftoff_xdot', 0.0))
        res.liftoff_pitch_rate = float(f.get('liftoff_pitch_rate', 0.0))
        res.flight_time = float(f.get('flight_time', 0.0))
        res.peak_flywheel_speed = float(f.get('peak_flywheel_speed', 0.0))
        res.solve_time = float(f.get('solve_time', 0.0))
        return res

    def _on_event(self, ev):
        if self.session is None:
            return
        state = measured_state(ev)
        try:
            if ev.event == ContactEvent.LIFT_OFF:
                ref = self.session.flight_reference(state)
            elif ev.event == ContactEvent.TOUCH_DOWN:
                ref = self.session.landing_reference(state)
            else:
                return
        except (InfeasibleRequest, ValueError, RuntimeError) as e:
            self.node.get_logger().error(f'replanning at contact event failed: {e}')
            return
        if ref is not None:
            if ref.domain == FlipReference.DOMAIN_FLIGHT:
                self.turns.shift_flight(ref)
            msg = self._publish(ref, state.t)
            sc = state.support_center
            self._publish_geometry(msg, com=state.com, com_velocity=state.com_velocity, foot_z=float(sc[2]),
                                   landing_foot_z=float(sc[2]) - self.session.platform
                                   if ev.event == ContactEvent.LIFT_OFF else None)
        if ev.event == ContactEvent.TOUCH_DOWN:
            self.turns.touch_down(state.pelvis_pitch)
            said = landing_attempt_note(ref.figures) if ref is not None else None
            if said:
                self.node.get_logger().warn(said)
            if ref is not None and ref.figures.get('predictions_left'):
                self.node.get_logger().info(
                    f'{ref.figures["predictions_left"]:.0f} landing prediction solves left from the lift-off done '
                    f'at the touch-down first, in {1e3 * ref.figures["predictions_left_time"]:.1f} ms')
        elif ref is not None:
            # the flight reference is out (the simulator holds for it alone): solve the landings this
            # lift-off predicts now, so that the touch-down's re-solve starts warm next to its answer;
            # stopped before a solve that would end after the planned touch-down (a touch-down waits for it)
            # or once a contact event comes (the solve under way abandoned; the touch-down solves what it needs)
            end = state.t + float(ref.parameters.get('flight_time', 0.0))     # the planned touch-down
            budget = PredictionBudget(self._sim_now, state.t, end)
            took = self.session.predict_landing(state, stop=lambda: self._event_waiting() or budget(),
                                                interrupt=self._event_waiting)
            if took is not None:
                self.node.get_logger().info(f'landing predicted from the lift-off in {1e3 * took:.1f} ms')
            while self._waiting:
                self._on_event(self._waiting.pop(0))

    def _event_waiting(self) -> bool:
        """Has a contact event come (taken from the subscription's queue into ``_waiting``)?"""
        got = self._events.handle.take_message(self._events.msg_type, False)
        if got is not None:
            self._waiting.append(got[0])
        return bool(self._waiting)


def main(args=None):
    rclpy.init(args=args)
    node = PlannerNode()
    def close():
        node._clock.destroy()
        node._clock_node.destroy_node()
        node.node.destroy_node()
        rclpy.try_shutdown()
    return run_until_stopped(lambda: rclpy.spin(node.node), close)


if __name__ == '__main__':
    sys.exit(main())
