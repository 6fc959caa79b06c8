"""The messages sim_node sends: the per-step state, /clock and the feet's wrenches from preallocated
serialized templates (through rcl's C API, ``_rcl_io``, or rclpy), and the contact events
(:class:`SimPublishing`, a part of :class:`sim_node.SimNode`)."""
from __future__ import annotations

from flip_msgs.msg import ContactEvent
from flip_transport import _rcl_io
from flip_transport.lockstep import (MessageReader, RawMessage, joint_state_layout, motor_command_layout, ns_to_stamp,
                                     odometry_layout, wrench_stamped_layout)
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from .contacts import Event
from .foot_wrench import FOOT_LINKS


def domain_entered(event):
    """LIFT_OFF enters FLIGHT, TOUCH_DOWN enters LANDING (flip_msgs/ContactEvent domains)."""
    return ContactEvent.DOMAIN_FLIGHT if event.kind == Event.LIFT_OFF else ContactEvent.DOMAIN_LANDING


class SimPublishing:
    """SimNode's publishing: the messages preallocated once, then stamped and sent per step."""

    def _prealloc_messages(self):
        n = len(self.sim.joint_names)
        self.msg_clock = RawMessage(Clock())
        self.msg_js = RawMessage(JointState(name=list(self.sim.joint_names), position=[0.0] * n,
                                            velocity=[0.0] * n, effort=[0.0] * n), joint_state_layout)
        odom = Odometry(child_frame_id='pelvis')
        odom.header.frame_id = 'world'
        self.msg_odom = RawMessage(odom, odometry_layout)
        self.read_command = MessageReader(motor_command_layout)
        self.msg_wrench = []
        for link in FOOT_LINKS:
            w = WrenchStamped()
            w.header.frame_id = link
            self.msg_wrench.append(RawMessage(w, wrench_stamped_layout))

    def _publish_clock(self, k):
        if self.rcl_io:
            _rcl_io.publish(self._ptr['clock'], self.msg_clock.buf, k * self.dt_ns)
        else:
            self.msg_clock.stamp(k * self.dt_ns)
            self.pub_clock.publish(self.msg_clock.data())
        self.clock_k = k

    def _publish_state(self, k):
        ns = k * self.dt_ns
        js, od = self.msg_js.fields, self.msg_odom.fields
        self.sim.state_into(js['position'], js['velocity'], js['effort'], od['pose'], od['twist'])
        if k % self.clock_every == 0 and k != self.clock_k:
            self._publish_clock(k)
        if self.rcl_io:
            _rcl_io.publish(self._ptr['odom'], self.msg_odom.buf, ns)
            _rcl_io.publish(self._ptr['js'], self.msg_js.buf, ns)
            return
        for m in (self.msg_odom, self.msg_js):
            m.stamp(ns)
        self.pub_odom.publish(self.msg_odom.data())
        self.pub_js.publish(self.msg_js.data())

    def _publish_wrenches(self, k):
        """The feet's wrenches of state k (the simulator's, from its step out of k), stamped k·dt."""
        ns = k * self.dt_ns
        for pub, msg, w in zip(self.pub_wrench, self.msg_wrench, self.sim.wrenches):
            msg.fields['wrench'][:] = w
            if self.rcl_io:
                _rcl_io.publish(pub.handle.pointer, msg.buf, ns)
            else:
                msg.stamp(ns)
                pub.publish(msg.data())

    def _publish_event(self, k, event):
        msg = ContactEvent()
        ns_to_stamp(k * self.dt_ns, msg.header.stamp)
        msg.header.frame_id = 'world'
        msg.step = k
        msg.event = int(event.kind)
        msg.domain = domain_entered(event)
        pos, quat = self.sim.pelvis_pose()
        lin_w, ang_w = self.sim.pelvis_twist('world')
        msg.pelvis_pose.position.x, msg.pelvis_pose.position.y, msg.pelvis_pose.position.z = map(float, pos)
        o = msg.pelvis_pose.orientation
        o.w, o.x, o.y, o.z = map(float, quat)
        msg.pelvis_twist.linear.x, msg.pelvis_twist.linear.y, msg.pelvis_twist.linear.z = map(float, lin_w)
        msg.pelvis_twist.angular.x, msg.pelvis_twist.angular.y, msg.pelvis_twist.angular.z = map(float, ang_w)
        c, cv = self.sim.com_position(), self.sim.com_velocity()
        msg.com_position.x, msg.com_position.y, msg.com_position.z = map(float, c)
        msg.com_velocity.x, msg.com_velocity.y, msg.com_velocity.z = map(float, cv)
        msg.centroidal_pitch_momentum = float(self.sim.centroidal_pitch_momentum())
        fl, fr = self.sim.foot_normal_forces()
        msg.left_normal_force, msg.right_normal_force = float(fl), float(fr)
        sc = msg.support_center
        sc.x, sc.y, sc.z = map(float, self.sim.support_center())
        self.pub_events.publish(msg)
        self.node.get_logger().info(
            f"t={k * self.dt:.4f} s: {event.kind.name} -> domain {msg.domain}")

    def _publish_body_contact(self, k, bodies):
        msg = ContactEvent()
        ns_to_stamp(k * self.dt_ns, msg.header.stamp)
        msg.header.frame_id = ','.join(bodies)
        msg.step = k
        msg.event = ContactEvent.BODY_CONTACT
        pos, quat = self.sim.pelvis_pose()
        msg.pelvis_pose.position.x, msg.pelvis_pose.position.y, msg.pelvis_pose.position.z = map(float, pos)
        o = msg.pelvis_pose.orientation
        o.w, o.x, o.y, o.z = map(float, quat)
        self.pub_events.publish(msg)
        self.node.get_logger().warn(f't={k * self.dt:.4f} s: {", ".join(bodies)} touching the terrain')
