"""tsc_node: the task-space controller as a ROS 2 node (thin adapter around ``Controller``).

Per simulator step k it takes ``/joint_states`` and ``/odom`` stamped k·dt, computes the 11 motor
torques and publishes one ``/motor_command`` with ``step == k``. A state seen again (the simulator
re-sends on a timeout) gets the same command again: the node is idempotent per step. References
(``/fslip/reference``) and contact events (``/contact_events``) switch the domain; with neither,
the controller holds the standing pose. In lockstep, a contact event while a flip plan is in force
holds the simulator until it has seen the planner's reference for the domain entered; the node holds
its answer to that step the same way, since the reference may reach it after the state does (two
topics, no order between them): the step's command then never depends on which came first.

The per-step messages stay serialized (``flip_transport.lockstep``): the state is read from
numpy views of the received bytes, the command patched into a preallocated one. The simulator
publishes ``/odom`` before ``/joint_states``, so the node wakes on ``/joint_states`` alone. By
default rcl's C API waits for them and publishes the command (``flip_transport._rcl_io``), with
rclpy's subscriptions and publisher; ``rcl_io:=false`` does the same through rclpy's Python.
"""
from __future__ import annotations

import sys
import time

import numpy as np
import rclpy
from flip_msgs.msg import ContactEvent, FlipReference, MotorCommand
from flip_transport import _rcl_io
from flip_transport.lockstep import (LATCHED_QOS, PLANNER_HOLD_TIMEOUT_S, STREAM_QOS, MessageReader, RawMessage,
                                     SubscriptionSet, cpu_per_step_line, joint_state_layout,
                                     motor_command_layout, odometry_layout,
                                     holds_for_reference, pin_to_lockstep_cpu, read_stamp_ns,
                                     reference_answers, scheduling_note, stamp_to_ns)
from flip_transport.node_stop import run_until_stopped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from .config import config_overrides
from .domains import Controller
from .dynamics import MOTOR_NAMES
from .reference import SampledReference

DT_NS = 500_000
#: longest wall time the node holds a contact event's step for the planner's reference (the simulator's)
REFERENCE_HOLD_TIMEOUT_S = PLANNER_HOLD_TIMEOUT_S
#: topics that wake the node: all but /odom, which comes before /joint_states
WAKE_TOPICS = ('/joint_states', '/contact_events', '/fslip/reference', '/robot_description_mjcf')
#: the topics besides the state's (taken with rclpy also when rcl's C API waits: _rcl_io.StateWait)
OTHER_TOPICS = ('/contact_events', '/fslip/reference', '/robot_description_mjcf')


class TscNode:
    def __init__(self):
        self.node = rclpy.create_node('tsc_node')
        self.subs = SubscriptionSet(self.node, [
            (JointState, '/joint_states', STREAM_QOS),
            (Odometry, '/odom', STREAM_QOS),
            (ContactEvent, '/contact_events', LATCHED_QOS),
            (FlipReference, '/fslip/reference', LATCHED_QOS),
            (String, '/robot_description_mjcf', LATCHED_QOS),
        ], raw=('/joint_states', '/odom'))
        # /motor_command's publisher comes with the controller (_on_message): the simulator waits for a
        # publisher of it before its first step, so a publisher means a controller that answers (made
        # here, the simulator could step before the controller existed: in one graph run it was built
        # from /robot_description_mjcf 0.19 s after the first state was sent)
        self.pub = self.pub_ptr = None
        self.controller = None
        # leg motors' no-load speeds x this: the same robot as the simulator's (sim_node parameter)
        self.motor_speed_scale = float(self.node.declare_parameter('motor_speed_scale', 1.0).value)
        # flywheel motor's torque limit, N·m (0 = the flywheel's own): the simulator's (sim_node parameter)
        self.flywheel_torque = float(self.node.declare_parameter('flywheel_torque', 0.0).value)
        # controller settings (ControllerConfig fields) as a JSON object; checked here, before any
        # controller is built: a bad one stops the node with the reason
        self.overrides = config_overrides(self.node.declare_parameter('controller', '').value)
        # wait for the state and publish the command through rcl's C API (flip_transport._rcl_io)
        # instead of rclpy's Python (the same messages; false: the Python path, e.g. to compare)
        self.rcl_io = bool(self.node.declare_parameter('rcl_io', True).value)
        # recorders of /motor_command (besides the simulator) to match before the first answer: the
        # simulator re-sends its first state until then, and no command is lost to a late match
        # (a recorder matched 0.12-0.6 s in and missed the first 245-1,190 commands)
        self.min_subscribers = int(self.node.declare_parameter('min_subscribers', 0).value)
        self.matched = self.min_subscribers <= 0
        # lockstep: hold the answer to a contact event's step until the planner's reference for the
        # domain it enters has come (module doc); false in realtime mode, where the simulator does not wait
        self.hold_for_reference = bool(self.node.declare_parameter('hold_for_reference', True).value)
        self.plan_in_force = None   # (plan id, domain, start ns) of the newest reference
        self.awaited = None         # (domain, event ns, wall s): the reference a contact event waits for
        self.state_held = False     # a state is waiting for that reference
        self.state_wait = None
        self.pending = []           # references that came before the robot description
        self.cmd = RawMessage(MotorCommand(name=list(MOTOR_NAMES), effort=[0.0] * len(MOTOR_NAMES)),
                              motor_command_layout)
        self.js = self.odom = None          # the newest serialized /joint_states and /odom
        self.read_js, self.read_odom = MessageReader(joint_state_layout), MessageReader(odometry_layout)
        self.answered_ns = -1
        self.tick_us = []
        self.cpu0 = None            # (process, main thread) CPU time at the first tick

    def _on_reference(self, msg):
        try:
            ref = SampledReference.from_msg(msg)
        except ValueError as e:          # samples not len(t) x len(output_names), an unknown domain
            self.node.get_logger().error(f'malformed /fslip/reference ignored: {e}')
            return
        self.controller.set_reference(ref)
        self.plan_in_force = (msg.plan_id, msg.domain, stamp_to_ns(msg.start_time))
        self.node.get_logger().info(f'reference: plan {msg.plan_id} domain {msg.domain}, '
                                    f'{len(msg.t)} samples from t={ref.start_time:.3f} s')

    def _await_reference(self, msg):
        """A LIFT_OFF / TOUCH_DOWN while a flip plan is in force: its step waits for the planner's
        reference of the domain entered (sim_node's hold at the same event)."""
        if (self.hold_for_reference and msg.event in (ContactEvent.LIFT_OFF, ContactEvent.TOUCH_DOWN)
                and holds_for_reference(self.plan_in_force)):
            self.awaited = (msg.domain, stamp_to_ns(msg.header.stamp), time.monotonic())

    def _reference_missing(self, k_ns) -> bool:
        """Is step ``k_ns`` a contact event's (or later) whose reference has not come yet?  Past
        REFERENCE_HOLD_TIMEOUT_S the step is answered without it, as the simulator steps on."""
        if self.awaited is None or k_ns < self.awaited[1]:
            return False
        domain, event_ns, t0 = self.awaited
        if reference_answers(self.plan_in_force, domain, event_ns, DT_NS):
            self.awaited = None
            return False
        if time.monotonic() - t0 > REFERENCE_HOLD_TIMEOUT_S:
            self.node.get_logger().warn(f'no reference for domain {domain} within {REFERENCE_HOLD_TIMEOUT_S:g} s '
                                        f'of the contact event at t={event_ns * 1e-9:.4f} s: answering without it')
            self.awaited = None
            return False
        return True

    def _state(self, js_buf, odom_buf):
        """(q, v) from the serialized /joint_states and /odom: compiled from the bytes while the
        messages keep the layout of the last ones read through numpy views (StateConverter.from_cdr);
        a message of another layout (the first, other names) is read here and its layout handed on."""
        conv = self.controller.model_info
        qv = conv.from_cdr(js_buf, odom_buf)
        if qv is not None:
            return qv
        js, od = self.read_js(js_buf), self.read_odom(odom_buf)
        pose, twist = od['pose'], od['twist']
        qv = conv.from_ros(self.read_js.names[0], js['position'], js['velocity'],
                           pose[:3], pose[3:], twist[:3], twist[3:])
        conv.use_cdr_layout(self.read_js.layout(), self.read_odom.layout())
        return qv

    def _answer(self, k_ns, js_buf, odom_buf):
        if self.cpu0 is None:
            self.cpu0 = (time.process_time(), time.thread_time())
        q, v = self._state(js_buf, odom_buf)
        t0 = time.perf_counter()
        n_dropped, n_own = len(self.controller.dropped), len(self.controller.landing_fallbacks)
        n_rebounds = len(self.controller.rebounds)
        u, _ = self.controller.compute(q, v, k_ns * 1e-9, details=False)
        dt_us = (time.perf_counter() - t0) * 1e6
        if len(self.controller.landing_fallbacks) > n_own:
            t, why = self.controller.landing_fallbacks[-1]
            # (flip run reads this line into summary.json's landing_fallbacks)
            self.node.get_logger().warn(f'landing fallback: own landing from t={t:.4f} s ({why})')
        if len(self.controller.rebounds) > n_rebounds and self.controller.cfg.rebound_keeps_landing_plan:
            self.node.get_logger().info(f'rebound at t={self.controller.rebounds[-1]:.4f} s: the landing plan '
                                        f'goes on until the next touch-down is re-solved')
        if len(self.controller.dropped) > n_dropped:
            plan, start, t = self.controller.dropped[-1]
            self.node.get_logger().warn(f'plan {plan}: jumping reference from t={start:.3f} s not started: '
                                        f'the robot was not standing until t={t:.3f} s (at most {self.controller.cfg.max_late:g} s late)')
        self.tick_us.append(dt_us)
        cmd = self.cmd
        cmd.fields['step'][0] = k_ns // DT_NS
        cmd.fields['effort'][:] = u
        cmd.fields['compute_time_us'][0] = dt_us
        self._publish_command(k_ns)
        self.answered_ns = k_ns

    def _publish_command(self, k_ns):
        if self.rcl_io:
            _rcl_io.publish(self.pub_ptr, self.cmd.buf, k_ns)
        else:
            self.cmd.stamp(k_ns)
            self.pub.publish(self.cmd.data())

    def _on_state(self, js_buf, odom_buf):
        """A /joint_states and the /odom of the same step: answer it (again, for a re-sent one)."""
        if not self.matched:
            if self.pub.get_subscription_count() < 1 + self.min_subscribers:
                return
            self.matched = True
        k_js = read_stamp_ns(js_buf)
        if k_js == self.answered_ns:
            self._publish_command(k_js)          # the simulator asked again: same answer
        elif k_js > self.answered_ns or k_js == 0:
            self.state_held = self._reference_missing(k_js)
            if not self.state_held:
                self._answer(k_js, js_buf, odom_buf)

    def _on_message(self, topic, msg):
        """A message of one of OTHER_TOPICS."""
        if topic == '/robot_description_mjcf':
            self.controller = Controller(msg.data, motor_speed_scale=self.motor_speed_scale,
                                         flywheel_torque=self.flywheel_torque, **self.overrides)
            if self.pub is None:
                self.pub = self.node.create_publisher(MotorCommand, '/motor_command', STREAM_QOS)
                self.pub_ptr = self.pub.handle.pointer
            self.node.get_logger().info('controller built from /robot_description_mjcf'
                                        + (f', settings {self.overrides}' if self.overrides else '')
                                        + f'; {scheduling_note()}')
            for m in self.pending:
                self._on_reference(m)
            self.pending.clear()
        elif topic == '/fslip/reference':
            if self.controller is None:
                self.pending.append(msg)
            else:
                self._on_reference(msg)
        elif topic == '/contact_events' and self.controller is not None:
            self.controller.on_contact_event(msg.event, msg.domain, stamp_to_ns(msg.header.stamp) * 1e-9)
            self._await_reference(msg)

    def run(self):
        if self.rcl_io:
            return self._run_rcl()
        while rclpy.ok():
            odom_behind = self.js is not None and (self.odom is None or
                                                   read_stamp_ns(self.odom) < read_stamp_ns(self.js))
            taken = self.subs.wait(1.0, on=None if odom_behind else WAKE_TOPICS)
            if self.subs.interrupted:
                break
            for topic, msg in taken:
                if topic == '/joint_states':
                    self.js = msg
                elif topic == '/odom':
                    self.odom = msg
                else:
                    self._on_message(topic, msg)
            if self.controller is None or self.js is None or self.odom is None:
                continue
            if read_stamp_ns(self.js) == read_stamp_ns(self.odom):
                self._on_state(self.js, self.odom)

    def _run_rcl(self):
        """run() with rcl's C API waiting for the state (_rcl_io.StateWait); the other topics' messages
        are taken with rclpy when it reports them."""
        others = [self.subs.subscription(t) for t in OTHER_TOPICS]
        sw = self.state_wait = _rcl_io.StateWait(
            self.node.context.handle.pointer, self.subs.sigint_guard.handle.pointer,
            self.subs.subscription('/joint_states').handle.pointer,
            self.subs.subscription('/odom').handle.pointer, [s.handle.pointer for s in others])
        while rclpy.ok():
            status = sw.wait(1_000_000_000)
            if status & sw.INTERRUPTED:
                break
            if status & sw.OTHER:
                for topic, sub in zip(OTHER_TOPICS, others):
                    while (got := sub.handle.take_message(sub.msg_type, sub.raw)) is not None:
                        self._on_message(topic, got[0])
            if (status & sw.STATE or self.state_held) and self.controller is not None:
                self._on_state(sw.js, sw.odom)   # a new state, or the held one once its reference came

    def close_io(self):
        if self.state_wait is not None:
            self.state_wait.close()

    def log_ticks(self):
        """The tick's compute times of this run, to the console only: it is written on the way
        out, after a stop has shut down the context that /rosout is published in."""
        if self.tick_us:
            a = np.asarray(self.tick_us)
            logger = rclpy.logging.get_logger('tsc_node_ticks')
            logger.info(f'{a.size} ticks: median {np.median(a):.0f} us, p99 {np.percentile(a, 99):.0f} us')
            # from the first tick to the way out (waiting costs no CPU), per tick
            logger.info(cpu_per_step_line(self.cpu0, a.size))


def main(args=None):
    pin_to_lockstep_cpu()
    rclpy.init(args=args)
    try:
        node = TscNode()
    except ValueError as e:          # a bad parameter (e.g. the controller settings): say why, stop
        print(f"tsc_node: {e}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    def close():
        node.log_ticks()
        node.close_io()
        node.subs.destroy()
        node.node.destroy_node()
        rclpy.try_shutdown()
    return run_until_stopped(node.run, close)


if __name__ == '__main__':
    sys.exit(main())
