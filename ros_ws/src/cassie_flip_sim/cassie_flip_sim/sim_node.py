"""sim_node: the MuJoCo simulator as a ROS 2 node (thin adapter around ``simulator.Simulator``).
The messages it sends are in :mod:`sim_publishing`, the commands and references it takes in
:mod:`sim_commands`.

Lockstep protocol, one 0.5 ms step k (docs/architecture.md):
  1. at a contact event, publish ``/contact_events``; while a flip plan is in force, hold until the
     planner's reference for the domain entered is on the graph (the paper's simulation does the
     same), so a run does not depend on the planner's wall time;
  2. publish ``/odom``, ``/joint_states`` stamped k·dt (``/joint_states`` last: the controller wakes
     on it), and ``/clock`` every ``clock_rate`` period (default 200 Hz: every 10th step) and at the
     last step;
  3. wait for the ``/motor_command`` with ``step == k`` (older ones are dropped; on a timeout the
     state is sent again and the silence is reported), apply it, step;
  4. every ``wrench_rate`` period (default 200 Hz: every 10th step, the steps of ``/clock``), publish
     each foot's ground contact wrench of state k (``foot_wrench``: the contact forces solved at
     state k, in the foot link's frame) on ``/left_foot/wrench``, ``/right_foot/wrench``, stamped k·dt.
The per-step messages are published from preallocated serialized templates and the commands read
from the received bytes (flip_transport's ``lockstep.RawMessage``, ``motor_command_layout``); in
lockstep, by default through rcl's C API (``flip_transport._rcl_io``: publish, and ``CommandWait`` for
the command), ``rcl_io:=false`` through rclpy's Python.  There the routine steps run back to back in
C++ (``_rcl_io.SimLoop``, native/rcl_io.cpp: publish, wait, MuJoCo step and contact detector, the GIL
released), which hands back to this loop whatever is not routine: a step with pre-step work (1.), a
wait that got no command (a re-send, a reference, a wrong size, an interrupt), the run's end, and every 200 steps
(services, and the stop's signal handler, which only Python runs: a stop ends the run at the next
such return, at a step's end); ``compiled_loop:=false`` keeps every step in Python (the same messages).
Modes: ``lockstep`` (default; with ``hold:=true`` nothing is sent before ``/sim/release`` is called:
``flip`` calls it once its recorder reports every per-step topic matched on the recorder's side, which
the subscription counts the node sees do not tell), ``realtime`` (the robot stays at step 0, its state
re-sent, until the controller has answered it, and with ``hold:=true`` until ``/sim/release`` is called,
as a robot leaves its gantry once its controller runs and the graph is up; then it steps on the wall clock
holding the latest command, counting late and missing ones; a silent controller gets motor
damping), and ``controller:=none``
(zero torques, no waiting).
A stop (SIGINT, SIGTERM) ends the loop at a step's end: the node installs its own handlers instead of
rclpy's, which shut the context down from another thread at once (a step then lost the messages it
had not yet published, and the run its last ``/clock`` and the summary lines of the log).
"""
from __future__ import annotations

import signal
import sys
import time

import numpy as np
import rclpy
from cassie_model.model import Scenario, export_mjcf
from cassie_model.urdf import export_urdf
from flip_msgs.msg import ContactEvent, FlipReference, MotorCommand
from flip_transport import _rcl_io
from flip_transport.lockstep import (LATCHED_QOS, STREAM_QOS, SubscriptionSet, cpu_per_step_line,
                                     pin_to_lockstep_cpu, scheduling_note)
from flip_transport.node_stop import run_until_stopped
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from std_srvs.srv import Trigger

from .foot_wrench import WRENCH_TOPICS
from .perturbation import PlantPerturbation, parse_plant, with_landing_offset
from .sim_commands import COMMAND_RESEND_S, PLANNER_HOLD_TIMEOUT_S, WATCHDOG_STEPS, SimCommands  # noqa: F401
from .sim_publishing import SimPublishing, domain_entered
from .simulator import Simulator

#: joint-side damping applied by the watchdog, N·m·s/rad
WATCHDOG_DAMPING = 5.0
#: default rate of /clock, Hz: sim time for the nodes that run on it (use_sim_time), not the lockstep's
#: step (each state carries its own stamp); at every step its three subscribers (recorder, planner,
#: `flip`) cost the simulator's loop ~30 us of the CPU it shares with the controller (bench_graph.py)
CLOCK_RATE_HZ = 200.0
#: once the subscribers have matched the simulator's publishers, the wall time left for their side
#: of the match before the first step (a best-effort reader drops what comes before it matches)
MATCH_SETTLE_S = 0.3
#: steps between the loop's turns of the services' executor (and, in the compiled loop, its returns)
SPIN_EVERY = 200
#: default rate of the feet's wrench topics (WRENCH_TOPICS), Hz (the steps of /clock and /tf)
WRENCH_RATE_HZ = 200.0


def make_scenario(name, platform_height, ground_offset, landing_height=0.0):
    """Terrain from the node's parameters: flat, a start platform (flip C; ``landing_height``: the
    ground from 0.4 m ahead that much higher, unknown to the planner) or a landing area higher than
    the planner is told (flip D)."""
    if name == 'flat':
        return Scenario.flat()
    if name == 'platform':
        return with_landing_offset(Scenario.platform(platform_height), landing_height)
    if name in ('raised', 'raised_landing'):
        return Scenario.raised_landing(ground_offset)
    raise ValueError(f"scenario must be 'flat', 'platform' or 'raised', not {name!r}")



def _declare(node, name, default):
    return node.declare_parameter(name, default).value


class SimNode(SimPublishing, SimCommands):
    """The simulator node: parameters and interfaces, the stepping loop; the messages it sends in
    :class:`SimPublishing`, the commands and references it takes in :class:`SimCommands`."""

    def __init__(self):
        self.stop_requested = False     # a SIGINT/SIGTERM came (request_stop): end at the step's end
        self.node = rclpy.create_node('sim_node')
        n = self.node
        self.mode = _declare(n, 'mode', 'lockstep')
        self.controller = _declare(n, 'controller', 'tsc')
        self.duration = float(_declare(n, 'duration', 0.0))
        # after a run that ended by its duration: keep the publishers until a stop comes, so that a
        # subscriber still holding a backlog (a stalled recorder) gets it; Fast DDS drops the samples
        # of a writer that is gone
        self.linger = bool(_declare(n, 'linger', False))
        flywheel = _declare(n, 'flywheel', 'I')
        inertia = float(_declare(n, 'flywheel_inertia', 0.0))
        mass = float(_declare(n, 'flywheel_mass', 0.0))
        scenario = make_scenario(_declare(n, 'scenario', 'flat'),
                                 float(_declare(n, 'platform_height', 0.5)),
                                 float(_declare(n, 'ground_offset', 0.1)),
                                 float(_declare(n, 'landing_height', 0.0)))
        # subscribers (besides a lockstep controller) to wait for before the first step, e.g. a
        # recorder: best-effort messages sent before a reader has matched are lost
        self.min_subscribers = int(_declare(n, 'min_subscribers', 0))
        # lockstep: publish the state and wait for the command through rcl's C API (_rcl_io) instead
        # of rclpy's Python (the same messages; false: the Python path, e.g. to compare the two)
        self.rcl_io = bool(_declare(n, 'rcl_io', True))
        # lockstep with rcl_io: the routine steps in C++ (_rcl_io.SimLoop; module doc); false: in Python
        self.compiled_loop = bool(_declare(n, 'compiled_loop', True))
        # hold until /sim/release (an orchestrator releases it once every reader has matched: the graph's
        # matching stalled deliveries for ~0.3 s): realtime at step 0, lockstep before it
        self.hold = bool(_declare(n, 'hold', False))
        self.released = not self.hold
        if self.mode not in ('lockstep', 'realtime'):
            raise ValueError(f"mode must be 'lockstep' or 'realtime', not {self.mode!r}")
        if self.controller not in ('tsc', 'none'):
            raise ValueError(f"controller must be 'tsc' or 'none', not {self.controller!r}")
        # leg motors' no-load speeds x this (1 = published Cassie motors; a design-study knob)
        speed_scale = float(_declare(n, 'motor_speed_scale', 1.0))
        # flywheel motor's torque limit, N·m (0 = the flywheel's own, 195; a design-study knob)
        flywheel_torque = float(_declare(n, 'flywheel_torque', 0.0))
        fw = (inertia, mass) if inertia > 0 and mass > 0 else flywheel
        self.sim = Simulator(flywheel=fw, scenario=scenario, motor_speed_scale=speed_scale,
                             flywheel_torque=flywheel_torque)
        self.scenario = scenario
        # the robot perturbed as the planner and controller are not told (robustness sweeps): the
        # knobs of cassie_flip_sim.perturbation as JSON; a delay or a push needs the Python loop
        plant = parse_plant(_declare(n, 'plant', ''))
        self.plant = PlantPerturbation(self.sim, plant) if plant else None
        if self.plant is not None:
            n.get_logger().info(self.plant.describe(self.sim))
            self.compiled_loop = self.compiled_loop and not self.plant.per_step
        self.dt = self.sim.timestep
        self.dt_ns = int(round(self.dt * 1e9))
        # /clock every clock_every steps (clock_rate <= 0 or >= the step rate: every step)
        clock_rate = float(_declare(n, 'clock_rate', CLOCK_RATE_HZ))
        self.clock_every = max(1, int(round(1.0 / (clock_rate * self.dt)))) if clock_rate > 0 else 1
        self.clock_k = -1               # step of the newest /clock published
        # the feet's wrenches every wrench_every steps (wrench_rate <= 0: none; >= the step rate: every step)
        wrench_rate = float(_declare(n, 'wrench_rate', WRENCH_RATE_HZ))
        self.wrench_every = max(1, int(round(1.0 / (wrench_rate * self.dt)))) if wrench_rate > 0 else 0

        self._create_interfaces()
        self._prealloc_messages()
        self.pub_mjcf.publish(String(data=export_mjcf(self.sim.flywheel)))   # with its torque limit
        self.pub_urdf.publish(String(data=export_urdf(self.sim.flywheel)))
        self.command = np.zeros(11)
        self.plan_in_force = None      # (plan_id, domain) of the newest reference seen
        self.hold_times = []
        self.resends = 0
        self.reset_requested = False
        self.body_contact = False
        self.command_wait = None        # _rcl_io.CommandWait of a lockstep run (rcl_io)
        self.sim_loop = None            # _rcl_io.SimLoop of a lockstep run (rcl_io, compiled_loop)
        self.malformed_commands = 0     # /motor_command messages that were no MotorCommand (Python path)
        self._u_in = np.zeros(11)       # the command it reads
        self._ptr = {name: pub.handle.pointer for name, pub in
                     (('odom', self.pub_odom), ('js', self.pub_js), ('clock', self.pub_clock))}

    def _create_interfaces(self):
        """The publishers, the command and reference subscriptions, and the services (on a second
        node)."""
        n = self.node
        self.pub_clock = n.create_publisher(Clock, '/clock', STREAM_QOS)
        self.pub_js = n.create_publisher(JointState, '/joint_states', STREAM_QOS)
        self.pub_odom = n.create_publisher(Odometry, '/odom', STREAM_QOS)
        self.pub_events = n.create_publisher(ContactEvent, '/contact_events', LATCHED_QOS)
        self.pub_wrench = [n.create_publisher(WrenchStamped, topic, STREAM_QOS) for topic in WRENCH_TOPICS]
        # the MJCF (the controller's model, with this robot's flywheel and torque limit) and the URDF
        # of the same model (robot_state_publisher's topic: tf, viewers)
        self.pub_mjcf = n.create_publisher(String, '/robot_description_mjcf', LATCHED_QOS)
        self.pub_urdf = n.create_publisher(String, '/robot_description', LATCHED_QOS)
        self.subs = SubscriptionSet(n, [(MotorCommand, '/motor_command', STREAM_QOS),
                                        (FlipReference, '/fslip/reference', LATCHED_QOS)],
                                    raw=('/motor_command',))
        # Services are served by a second node spun by an executor between steps.
        self.srv_node = rclpy.create_node('sim_node_services')
        self.srv_node.create_service(Trigger, '/sim/reset', self._on_reset)
        self.srv_node.create_service(Trigger, '/sim/release', self._on_release)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.srv_node)

    # -- stop and services -------------------------------------------------------------------
    def request_stop(self, signum=None, frame=None):
        """Signal handler: the loop ends once the step under way has ended (see the module doc)."""
        self.stop_requested = True

    def _running(self):
        return not self.stop_requested and rclpy.ok()

    def _on_reset(self, request, response):
        self.reset_requested = True
        response.success = True
        response.message = 'reset to standing at the next step'
        return response

    def _on_release(self, request, response):
        response.success = self.mode == 'realtime' or self.hold
        response.message = ('released: on the wall clock' if self.mode == 'realtime' else
                            'released: lockstep from step 0' if self.hold else
                            f'nothing to release in {self.mode} mode without hold')
        self.released = True
        return response

    def _wait_for_release(self):
        """Lockstep with ``hold``: no state before /sim/release (module doc); False when stopped meanwhile."""
        if self.mode != 'lockstep' or self.released:
            return True
        self.node.get_logger().info('held before step 0 until /sim/release')
        while not self.released:
            self.executor.spin_once(timeout_sec=0.01)
            if not self._running():
                return False
        return True

    def _hold_at_start(self):
        """Realtime: step 0's command, the state re-sent until it comes and (``hold``) until
        /sim/release. Returns the newest command, or None when the run was stopped."""
        cmd = self._wait_command(0)
        t_sent = time.monotonic()
        while cmd is not None and not self.released:
            newer = self._newest_command(self.subs.take_all(), 0)
            cmd = cmd if newer is None else newer
            self.executor.spin_once(timeout_sec=0.005)
            if not self._running():
                return None
            if time.monotonic() - t_sent >= COMMAND_RESEND_S:
                self._publish_state(0)
                t_sent = time.monotonic()
        return cmd

    # -- main loop ---------------------------------------------------------------------------
    def run(self):
        log = self.node.get_logger()
        if not self._wait_for_subscribers() or not self._wait_for_release():
            return 0
        n_steps = int(round(self.duration / self.dt)) if self.duration > 0 else None
        self._start_rcl_io()
        log.info(f'running: mode={self.mode} controller={self.controller} '
                 f'duration={self.duration or "forever"} s flywheel={self.sim.flywheel} '
                 f'flywheel_torque={getattr(self.sim.flywheel, "max_torque", None)} N·m'
                 f'; foot wrenches {f"every {self.wrench_every} steps" if self.wrench_every else "off"}'
                 f'{"; compiled loop" if self.sim_loop is not None else ""}; {scheduling_note()}')
        wall0 = t_start = time.monotonic()
        cpu0 = (time.process_time(), time.thread_time())
        k = 0
        self.last_state_k = -1
        late = self.missing = 0
        # wall time of the loop's parts (s, summed over the steps): the per-step budget in the log
        spent = {'simulate': 0.0, 'publish state': 0.0, 'wait for command': 0.0}
        clock = time.perf_counter
        self.last_cmd_k, self.damping = 0, False
        try:   # the summary also when SIGINT (KeyboardInterrupt) ends the run
            while self._running() and (n_steps is None or k < n_steps):
                self._pre_step(k)
                if self.sim_loop is not None:
                    k, handed_over = self._compiled_steps(k, n_steps, spent)
                    if handed_over is None:          # steps taken: step k's checks are this loop's
                        if k % SPIN_EVERY == 0:
                            self.executor.spin_once(timeout_sec=0.0)
                        continue
                    c1 = clock()                     # step k's state sent, its command awaited
                    cmd = self._wait_command_rcl(k, *handed_over)
                    spent['wait for command'] += clock() - c1
                    if cmd is None:
                        break
                    self.command[:] = cmd
                else:
                    c0 = clock()
                    self._publish_state(k)
                    self.last_state_k = k
                    c1 = clock()
                    spent['publish state'] += c1 - c0
                if self.controller == 'tsc' and self.sim_loop is None:
                    if self.mode == 'lockstep':
                        cmd = self._wait_command(k)
                        spent['wait for command'] += clock() - c1
                        if cmd is None:
                            break
                        self.command[:] = cmd
                    elif k == 0:
                        cmd = self._hold_at_start()
                        if cmd is None:
                            break
                        self.command[:] = cmd
                        wall0 = time.monotonic()
                        log.info(f'held at step 0 for {wall0 - t_start:.3f} s; on the wall clock from here')
                    else:
                        self._realtime_command(k)
                c2 = clock()
                wrench = self.wrench_every > 0 and k % self.wrench_every == 0
                u = self.command if self.plant is None else self.plant.command(self.sim, self.command)
                self.sim.step(u, wrench=wrench)
                c3 = clock()
                spent['simulate'] += c3 - c2
                if wrench:
                    self._publish_wrenches(k)
                    spent['publish state'] += clock() - c3
                k += 1
                if self.mode == 'realtime':
                    lag = wall0 + k * self.dt - time.monotonic()
                    if lag > 0:
                        time.sleep(lag)
                    elif lag < -self.dt:
                        late += 1       # more than one step behind the wall clock
                if k % SPIN_EVERY == 0:
                    self.executor.spin_once(timeout_sec=0.0)
        finally:
            self._log_summary(k, wall0, cpu0, spent, late)
        if self.linger and n_steps is not None and k >= n_steps:
            self._linger(k)
        return 0

    def _wait_for_subscribers(self):
        """Wait for ``min_subscribers`` (and a lockstep controller) to match the state's publishers and,
        with a controller, for its /motor_command; False when the run was stopped meanwhile."""
        log = self.node.get_logger()
        need = self.min_subscribers + (1 if self.controller == 'tsc' else 0)
        # lockstep: the controller's /motor_command matched here too (a command it sends before this side
        # has matched it is lost, and the state re-sent after COMMAND_RESEND_S).  The first state can still
        # be re-sent a few times (~0.25 s, in some graph runs: the controller's side of the match);
        # summary.json reports that wait apart (first_state_wait_s)
        cmd_sub = self.subs.subscription('/motor_command') if self.controller == 'tsc' else None
        if need:
            log.info(f'waiting for {need} subscriber(s) of /joint_states, /odom and /clock'
                     + (' and a publisher of /motor_command' if cmd_sub is not None else ''))
            pubs = (self.pub_js, self.pub_odom, self.pub_clock)
            while any(p.get_subscription_count() < (need if p is not self.pub_clock else self.min_subscribers)
                      for p in pubs) or (cmd_sub is not None and cmd_sub.get_publisher_count() < 1):
                self.executor.spin_once(timeout_sec=0.01)
                if not self._running():
                    return False
            settled = time.monotonic() + MATCH_SETTLE_S
            while time.monotonic() < settled and self._running():
                self.executor.spin_once(timeout_sec=0.01)
        return True

    def _start_rcl_io(self):
        """Lockstep with rcl_io: the command wait through rcl's C API and, with ``compiled_loop``, the
        routine steps in C++ (_rcl_io.SimLoop; module doc)."""
        log = self.node.get_logger()
        if self.rcl_io and self.mode == 'lockstep' and self.controller == 'tsc':
            self.command_wait = _rcl_io.CommandWait(
                self.node.context.handle.pointer, self.subs.subscription('/motor_command').handle.pointer,
                self.subs.subscription('/fslip/reference').handle.pointer, self.subs.sigint_guard.handle.pointer)
            parts = self.sim.native_loop_parts() if self.compiled_loop else None
            if parts is not None:
                js, od = self.msg_js.fields, self.msg_odom.fields
                self.sim_loop = _rcl_io.SimLoop(
                    self.command_wait, parts[0], self._ptr['odom'], self._ptr['js'], self._ptr['clock'],
                    self.msg_odom.buf, self.msg_js.buf, self.msg_clock.buf, js['position'], js['velocity'],
                    js['effort'], od['pose'], od['twist'], self.command, self._u_in, parts[1], self.dt_ns,
                    self.clock_every, int(COMMAND_RESEND_S * 1e9), SPIN_EVERY)
                if self.wrench_every:
                    (left, right), (ml, mr) = self.pub_wrench, self.msg_wrench
                    self.sim_loop.set_wrenches(left.handle.pointer, right.handle.pointer, ml.buf, mr.buf,
                                               ml.fields['wrench'], mr.fields['wrench'], self.wrench_every)
            elif self.compiled_loop:
                log.warn('compiled loop unavailable for this simulator: the loop steps in Python')

    def _pre_step(self, k):
        """Step k's pre-step work: a requested reset, the contact events (in lockstep held for the
        planner's reference), a body's contact with the terrain."""
        log = self.node.get_logger()
        if self.reset_requested:
            self.sim.reset()
            self.reset_requested = False
            log.info('reset to standing')
        for event in self.sim.pop_events():
            self._publish_event(k, event)
            if self.plant is not None:
                self.plant.on_event(event)
            if self.mode == 'lockstep':
                self._hold_for_reference(k, domain_entered(event))
        touching = self.sim.body_contacts()
        if touching and not self.body_contact:
            self._publish_body_contact(k, touching)
        self.body_contact = bool(touching)

    def _realtime_command(self, k):
        """Realtime, step k > 0: the newest command, or the watchdog's motor damping once the controller
        has been silent for WATCHDOG_STEPS."""
        log = self.node.get_logger()
        cmd = self._newest_command(self.subs.take_all(), k)
        if cmd is not None:
            self.command[:] = cmd
            self.last_cmd_k = k
        else:
            self.missing += 1
            if k - self.last_cmd_k > WATCHDOG_STEPS:
                if not self.damping:
                    log.warn(f'controller silent for {(k - self.last_cmd_k) * self.dt * 1e3:.0f}'
                             ' ms: motors to damping')
                self.damping = True
                self.command[:] = -WATCHDOG_DAMPING * self.sim.motor_velocities()
        if cmd is not None and self.damping:
            log.info('controller back: damping released')
            self.damping = False

    def _log_summary(self, k, wall0, cpu0, spent, late):
        """The run's last /clock and its summary lines (also when a stop ended it): steps, real-time
        factor, re-sends, holds, and the loop's per-step budget."""
        log = self.node.get_logger()
        wall = time.monotonic() - wall0
        if self.last_state_k > self.clock_k and rclpy.ok():    # sim time up to the last state sent
            self._publish_clock(self.last_state_k)
        sim_t = k * self.dt
        log.info(f'done: {k} steps, {sim_t:.3f} s sim in {wall:.3f} s wall '
                 f'(real-time factor {sim_t / wall if wall > 0 else float("nan"):.2f}); '
                 f'state re-sent {self.resends} times; planner holds {len(self.hold_times)}'
                 + (f'; realtime: {late} late steps, {self.missing} steps without a new command'
                    if self.mode == 'realtime' else ''))
        malformed = self.malformed_commands + (self.command_wait.malformed if self.command_wait else 0)
        if malformed:
            log.warn(f'{malformed} /motor_command messages that are not MotorCommand CDR ignored')
        if k:
            per = {name: 1e6 * v / k for name, v in spent.items()}
            per['planner holds'] = 1e6 * sum(self.hold_times) / k
            per['rest'] = max(1e6 * wall / k - sum(per.values()), 0.0)
            log.info('loop per step (mean us): ' + ', '.join(f'{n} {v:.0f}' for n, v in per.items()))
            log.info(cpu_per_step_line(cpu0, k))

    def _linger(self, k):
        """The run is over (its duration; /clock stands at its last state): serve nothing but
        keep the publishers until a stop comes."""
        self.node.get_logger().info(f'lingering at sim t = {k * self.dt:.3f} s until stopped')
        while self._running():
            self.executor.spin_once(timeout_sec=0.05)

    def _compiled_steps(self, k, n_steps, spent):
        """Steps from k (its pre-step checks done) in the compiled loop until it hands back (module
        doc), the simulator, the node's state and ``spent`` brought up to date. Returns (the next
        step, None), or (k, (the wait's status, when it began)) when step k's state is sent and its
        command is to be awaited further here (``_wait_command_rcl``)."""
        lp, sim = self.sim_loop, self.sim
        lp.clock_k, lp.sim_step, lp.body_contact = self.clock_k, sim.step_index, self.body_contact
        lp.clip, lp.detector = sim.clip_torques, sim.detector.state()
        reason, k = lp.run(k, -1 if n_steps is None else n_steps)
        sim.note_native_steps(lp.steps, lp.forces, lp.detector, lp.event)
        simulate, publish, wait = lp.spent
        spent['simulate'] += simulate
        spent['publish state'] += publish
        spent['wait for command'] += wait
        self.clock_k = lp.clock_k
        if lp.last_state_k >= 0:
            self.last_state_k = lp.last_state_k
        return k, ((lp.wait_status, lp.wait_t0) if reason == lp.WAIT else None)

    def close_io(self):
        if self.command_wait is not None:
            self.command_wait.close()


def main(args=None):
    pin_to_lockstep_cpu()
    # no rclpy signal handlers: they shut the context down at once; the node's own end the loop
    # between steps (module doc); until the node exists, a stop ends the process as Python's would
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = SimNode()
    except (ValueError, FileNotFoundError) as e:
        print(f'sim_node: {e}', file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    signal.signal(signal.SIGINT, node.request_stop)
    signal.signal(signal.SIGTERM, node.request_stop)
    def close():
        node.close_io()
        node.subs.destroy()
        node.node.destroy_node()
        node.srv_node.destroy_node()
        rclpy.try_shutdown()
    return run_until_stopped(node.run, close)


if __name__ == '__main__':
    sys.exit(main())
