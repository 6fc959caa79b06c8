"""Lean rclpy transport for the 2 kHz lockstep: a wait set over a node's subscriptions, no executor,
and the per-step messages handled as serialized (CDR) bytes.

The simulator and the controller exchange one state and one command per 0.5 ms step. An rclpy
executor costs several hundred microseconds per round trip on this machine kind
(docs/architecture.md); a wait set re-armed before every wait and ``take_message`` on the ready
subscriptions does not. Converting messages costs too (deserialising an Odometry ~70 µs, a
JointState ~25 µs): the per-step messages are published from a preallocated serialized template
patched in place (:class:`RawMessage`) and read as numpy views of the received bytes
(:func:`fields` of a ``*_layout``). The wait-set API is rclpy's private ``_rclpy`` binding, pinned
with rclpy 7.1.6 and covered by the node tests.

Subscriptions used here must belong to a node that no executor spins (otherwise the executor
would take their messages first); their callbacks are never called.

The simulator and its controller take turns (never run at once), so they share one CPU
(:func:`pin_to_lockstep_cpu`): each hand-over is then a wake-up on the same CPU, not a
cross-CPU one (which costs hundreds of µs on a VM). There they run as ``SCHED_BATCH`` threads when
``$FLIP_LOCKSTEP_SCHED`` says so (`flip` does for a lockstep run): a thread woken by a message (the
partner's or a DDS receive thread) then waits for the running one to block instead of preempting it,
so a step's messages are published without a switch after each. bench_graph backflips, interleaved
with the default policy (SCHED_OTHER), 15 pairs: publish state 96-160 -> 29-50 µs a step in every
pair, the real-time factor higher in 11 of the 15 (median +0.06; README, Speed).
"""
from __future__ import annotations

import os
import time

from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile,
                       ReliabilityPolicy)
from rclpy.serialization import serialize_message
from rclpy.signals import SignalHandlerGuardCondition

# the readers of serialized messages (no ROS in them), here for the nodes that import them from here
from .cdr import (_STAMP, CdrCursor, MessageReader, fields, joint_state_layout,  # noqa: F401
                  motor_command_layout, odometry_layout, read_stamp_ns, wrench_stamped_layout)

#: state and command topics: newest only, no retransmission (a lost message is re-sent on timeout)
STREAM_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                        reliability=ReliabilityPolicy.BEST_EFFORT,
                        durability=DurabilityPolicy.VOLATILE)
#: events, references, robot description: every message, and a late joiner still gets them
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)

#: environment variable naming the CPU the lockstep partners share (set by flip_tools.launcher)
LOCKSTEP_CPU_ENV = 'FLIP_LOCKSTEP_CPU'
#: environment variable naming the scheduling policy of the pinned partners: 'batch' (SCHED_BATCH),
#: or 'other' / unset (left as started: SCHED_OTHER)
LOCKSTEP_SCHED_ENV = 'FLIP_LOCKSTEP_SCHED'
LOCKSTEP_SCHED_POLICIES = {'batch': os.SCHED_BATCH, 'other': os.SCHED_OTHER}


def pin_to_lockstep_cpu():
    """Pin every thread of this process to the CPU in ``$FLIP_LOCKSTEP_CPU``, with the scheduling
    policy of ``$FLIP_LOCKSTEP_SCHED`` (:func:`lockstep_policy`) (call before ``rclpy.init``: the
    DDS threads inherit both). Returns that CPU, or None (unset, or a CPU this process may not use:
    then the policy is left alone too)."""
    cpu = os.environ.get(LOCKSTEP_CPU_ENV, '')
    if not cpu.isdigit() or int(cpu) not in os.sched_getaffinity(0):
        return None
    policy = lockstep_policy()
    for tid in os.listdir('/proc/self/task'):
        os.sched_setaffinity(int(tid), {int(cpu)})
        if policy is not None:
            os.sched_setscheduler(int(tid), policy, os.sched_param(0))
    return int(cpu)


def avoid_lockstep_cpu():
    """Keep every thread of this process off the CPU in ``$FLIP_LOCKSTEP_CPU`` (call before
    ``rclpy.init``), for a reader of the lockstep's streams that must not preempt it. Returns the
    CPUs left, or None (unset, or no other CPU: then nothing changes)."""
    cpu = os.environ.get(LOCKSTEP_CPU_ENV, '')
    others = os.sched_getaffinity(0) - {int(cpu)} if cpu.isdigit() else set()
    if not others:
        return None
    for tid in os.listdir('/proc/self/task'):
        os.sched_setaffinity(int(tid), others)
    return sorted(others)


def scheduling_note():
    """'cpus [..], SCHED_...' of the calling thread, read back from the kernel (for a node's log)."""
    names = {os.SCHED_OTHER: 'SCHED_OTHER', os.SCHED_BATCH: 'SCHED_BATCH', os.SCHED_IDLE: 'SCHED_IDLE',
             os.SCHED_FIFO: 'SCHED_FIFO', os.SCHED_RR: 'SCHED_RR'}
    policy = os.sched_getscheduler(0)
    return f'cpus {sorted(os.sched_getaffinity(0))}, {names.get(policy, policy)}'


def lockstep_policy():
    """The policy ``$FLIP_LOCKSTEP_SCHED`` names (os.SCHED_BATCH for 'batch'), or None when it is
    unset or empty. Any other value is an error (ValueError), not a silent default."""
    name = os.environ.get(LOCKSTEP_SCHED_ENV, '')
    if not name:
        return None
    if name not in LOCKSTEP_SCHED_POLICIES:
        raise ValueError(f'{LOCKSTEP_SCHED_ENV}={name!r}: expected one of {sorted(LOCKSTEP_SCHED_POLICIES)}')
    return LOCKSTEP_SCHED_POLICIES[name]


def cpu_per_step_line(cpu0, steps):
    """'cpu per step (mean us): main thread M, other threads O': this process's CPU time since
    ``cpu0`` = (process_time, main thread's thread_time), per step; the other threads are the
    middleware's (DDS receive and event threads). scripts/bench_graph.py reads the line."""
    proc, main = time.process_time() - cpu0[0], time.thread_time() - cpu0[1]
    n = max(steps, 1)
    return (f'cpu per step (mean us): main thread {1e6 * main / n:.0f}, '
            f'other threads {1e6 * max(proc - main, 0.0) / n:.0f}')


def _ignore(_msg):
    return None


class SubscriptionSet:
    """Subscriptions polled through one rclpy wait set.

    ``wait(timeout_s)`` blocks until at least one subscription has data (or the timeout, or
    SIGINT) and returns the list of ``(topic, message)`` taken, in subscription order. Topics in
    ``raw`` are taken as serialized bytes. A subscription of depth 1 (the per-step streams) holds
    at most one message and is taken once; a subscription in the wait set that the wait did not
    find ready is not taken at all (an empty take costs as much as a wait).
    """

    def __init__(self, node, subscriptions, raw=()):
        """``subscriptions``: list of ``(msg_type, topic, qos)``."""
        self._node = node
        self._subs = [node.create_subscription(t, topic, _ignore, qos, raw=topic in raw)
                      for t, topic, qos in subscriptions]
        self._topics = [topic for _, topic, _ in subscriptions]
        # (topic, subscription, its rcl pointer, take at most one message)
        self._entries = [(topic, sub, sub.handle.pointer,
                          qos.history == HistoryPolicy.KEEP_LAST and qos.depth == 1)
                         for (_, topic, qos), sub in zip(subscriptions, self._subs)]
        self._waited = {}            # `on` -> (entries in the wait set, pointers of those)
        self._sigint = SignalHandlerGuardCondition(context=node.context)
        self._wait_set = _rclpy.WaitSet(len(self._subs), 1, 0, 0, 0, 0, node.context.handle)
        self.interrupted = False

    def subscription(self, topic):
        return self._subs[self._topics.index(topic)]

    @property
    def sigint_guard(self):
        """The guard condition SIGINT triggers (rclpy's), which every wait includes."""
        return self._sigint

    def _take(self, skip=()):
        out = []
        for topic, sub, ptr, single in self._entries:
            if ptr in skip:
                continue
            if single:
                got = sub.handle.take_message(sub.msg_type, sub.raw)
                if got is not None:
                    out.append((topic, got[0]))
                continue
            while (got := sub.handle.take_message(sub.msg_type, sub.raw)) is not None:
                out.append((topic, got[0]))
        return out

    def take_all(self):
        """Every message already queued, without waiting."""
        return self._take()

    def wait(self, timeout_s, on=None):
        """Block until a message is queued on one of the topics ``on`` (default: every one), then
        take what is queued (e.g. wake on the last message of a step only): the subscriptions
        outside ``on`` are taken from unconditionally, those in it when the wait found them ready."""
        key = None if on is None else tuple(on)
        waited = self._waited.get(key)
        if waited is None:
            entries = [e for e in self._entries if on is None or e[0] in on]
            waited = self._waited[key] = (entries, frozenset(e[2] for e in entries))
        ws = self._wait_set
        ws.clear_entities()
        for e in waited[0]:
            ws.add_subscription(e[1].handle)
        ws.add_guard_condition(self._sigint.handle)
        ws.wait(int(timeout_s * 1e9) if timeout_s is not None and timeout_s >= 0 else -1)
        if ws.get_ready_entities('guard_condition'):
            self.interrupted = True
            return []
        ready = ws.get_ready_entities('subscription')
        return self._take(waited[1].difference(ready) if len(ready) < len(waited[0]) else ())

    def destroy(self):
        self._sigint.destroy()
        for sub in self._subs:
            self._node.destroy_subscription(sub)


def wait_for_subscribers(publisher, count=1, timeout_s=30.0, poll_s=0.01):
    """Block until ``publisher`` has matched ``count`` subscriptions (messages sent earlier are
    lost for best-effort readers). Returns whether it did within the timeout."""
    deadline = time.monotonic() + timeout_s
    while publisher.get_subscription_count() < count:
        if time.monotonic() > deadline:
            return False
        time.sleep(poll_s)
    return True


#: longest wall time a node holds a contact event's step for the planner's reference (sim_node, tsc_node)
PLANNER_HOLD_TIMEOUT_S = 30.0


def holds_for_reference(plan_in_force) -> bool:
    """In lockstep a LIFT_OFF / TOUCH_DOWN holds its step for the planner's reference while a flip plan
    is in force: the newest reference, ``(plan id, domain, start ns)``, is there and not STANDING's."""
    from flip_msgs.msg import FlipReference
    return plan_in_force is not None and plan_in_force[1] != FlipReference.DOMAIN_STANDING


def reference_answers(plan_in_force, domain, event_ns, dt_ns) -> bool:
    """Does the newest reference answer the contact event at ``event_ns`` entering ``domain``: that
    domain's, starting at the event's step or later (one step's rounding allowed)?"""
    return plan_in_force is not None and plan_in_force[1] == domain and plan_in_force[2] >= event_ns - dt_ns


def stamp_to_ns(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def ns_to_stamp(ns, stamp):
    """Fill a builtin_interfaces/Time in place from integer nanoseconds."""
    stamp.sec = int(ns // 1_000_000_000)
    stamp.nanosec = int(ns % 1_000_000_000)
    return stamp


# -- serialized messages: read with flip_transport.cdr (no ROS), written with RawMessage ----------
class RawMessage:
    """A message serialized once and published as bytes: its stamp and the fields a ``*_layout``
    function finds are patched in place (numpy views) before each publish."""

    def __init__(self, msg, layout=None):
        self.buf = bytearray(serialize_message(msg))
        self.fields = fields(self.buf, layout(self.buf)[1]) if layout else {}

    def stamp(self, ns):
        _STAMP.pack_into(self.buf, 4, ns // 1_000_000_000, ns % 1_000_000_000)

    def data(self):
        return bytes(self.buf)
