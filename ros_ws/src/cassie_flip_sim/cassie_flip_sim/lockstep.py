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
cross-CPU one (which costs hundreds of µs on a VM).
"""
from __future__ import annotations

import os
import struct
import time

import numpy as np
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile,
                       ReliabilityPolicy)
from rclpy.serialization import serialize_message
from rclpy.signals import SignalHandlerGuardCondition

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


def pin_to_lockstep_cpu():
    """Pin every thread of this process to the CPU in ``$FLIP_LOCKSTEP_CPU`` (call before
    ``rclpy.init``: the DDS threads inherit it). Returns that CPU, or None (unset, or a CPU this
    process may not use)."""
    cpu = os.environ.get(LOCKSTEP_CPU_ENV, '')
    if not cpu.isdigit() or int(cpu) not in os.sched_getaffinity(0):
        return None
    for tid in os.listdir('/proc/self/task'):
        os.sched_setaffinity(int(tid), {int(cpu)})
    return int(cpu)


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


def stamp_to_ns(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def ns_to_stamp(ns, stamp):
    """Fill a builtin_interfaces/Time in place from integer nanoseconds."""
    stamp.sec = int(ns // 1_000_000_000)
    stamp.nanosec = int(ns % 1_000_000_000)
    return stamp


# -- serialized messages ---------------------------------------------------------------------------
# A ``*_layout(buf, names=None)`` function returns ``(names, {field: (offset, count, dtype)})`` for
# one serialized message type: ``names`` its string[] (or None) as CdrCursor.strings gives it, to
# pass back for the next message. Its numeric fields are then read or written as numpy views.

#: a builtin_interfaces/Time (int32 sec, uint32 nanosec) first in the message, after the 4-byte
#: CDR encapsulation header: /clock's stamp and every std_msgs/Header's
_STAMP = struct.Struct('<iI')


def read_stamp_ns(buf):
    """Stamp (ns) of a serialized message that starts with a header or a time."""
    sec, nanosec = _STAMP.unpack_from(buf, 4)
    return sec * 1_000_000_000 + nanosec


_F8, _F4, _U8 = np.dtype('<f8'), np.dtype('<f4'), np.dtype('<u8')
_UINT = {4: struct.Struct('<I'), 8: struct.Struct('<Q')}


class CdrCursor:
    """Walks a serialized ROS 2 message as rmw_fastrtps writes it: little-endian CDR, a 4-byte
    encapsulation header, each field aligned to its size counted from the end of that header."""

    def __init__(self, buf, pos=4):
        self.buf, self.pos = buf, pos

    def _align(self, n):
        self.pos += -(self.pos - 4) % n

    def uint(self, size=4):
        self._align(size)
        v = _UINT[size].unpack_from(self.buf, self.pos)[0]
        self.pos += size
        return v

    def skip_string(self):
        n = self.uint()
        self.pos += n

    def strings(self, known=None):
        """A string[] as ``(names, bytes)``; ``known`` (an earlier result) is skipped by a byte
        compare when the buffer holds the same list here."""
        if known is not None and self.buf[self.pos:self.pos + len(known[1])] == known[1]:
            self.pos += len(known[1])
            return known
        start = self.pos
        names = []
        for _ in range(self.uint()):
            n = self.uint()
            names.append(bytes(self.buf[self.pos:self.pos + n - 1]).decode())
            self.pos += n
        return names, bytes(self.buf[start:self.pos])

    def field(self, dtype, n=None):
        """``(offset, count, dtype)`` of ``n`` values of ``dtype`` here (a sequence: count first;
        an empty one is not aligned)."""
        if n is None:
            n = self.uint()
        if n:
            self._align(dtype.itemsize)
        off = self.pos
        self.pos += n * dtype.itemsize
        return off, n, dtype


def joint_state_layout(buf, names=None):
    """sensor_msgs/JointState: ``(names, {position, velocity, effort})``."""
    c = CdrCursor(buf, 12)
    c.skip_string()                                     # header.frame_id
    names = c.strings(names)
    return names, {'position': c.field(_F8), 'velocity': c.field(_F8), 'effort': c.field(_F8)}


def odometry_layout(buf, names=None):
    """nav_msgs/Odometry: ``(None, {pose, twist})``, pose = position xyz and orientation xyzw,
    twist = linear and angular."""
    c = CdrCursor(buf, 12)
    c.skip_string()                                     # header.frame_id
    c.skip_string()                                     # child_frame_id
    pose = c.field(_F8, 7)
    c.field(_F8, 36)                                    # pose covariance
    return None, {'pose': pose, 'twist': c.field(_F8, 6)}


def motor_command_layout(buf, names=None):
    """flip_msgs/MotorCommand: ``(names, {step, effort, compute_time_us})``."""
    c = CdrCursor(buf, 12)
    c.skip_string()                                     # header.frame_id
    step = c.field(_U8, 1)
    names = c.strings(names)
    return names, {'step': step, 'effort': c.field(_F8), 'compute_time_us': c.field(_F4, 1)}


def fields(buf, layout):
    """Numpy views of ``buf`` for a layout's fields (read-only for ``bytes``)."""
    return {k: np.frombuffer(buf, dtype, n, off) for k, (off, n, dtype) in layout.items()}


class MessageReader:
    """Numpy views of the numeric fields of received serialized messages of one type (``layout``: a
    ``*_layout`` function).  The layout is worked out again only when a message differs from the
    last one outside its numeric fields and stamp, i.e. in its strings or sequence lengths: a 2 kHz
    stream from one publisher keeps the layout of its first message (a byte compare a message,
    instead of walking it).  ``names`` is the string[] of the last layout (as the layout function
    gives it)."""

    def __init__(self, layout):
        self._layout_fn = layout
        self.names = None
        self._size = -1
        self._const = ()         # (start, end, bytes) of the runs outside the numeric fields and stamp
        self._layout = None

    def __call__(self, buf):
        if len(buf) != self._size or any(buf[a:b] != c for a, b, c in self._const):
            self.names, self._layout = self._layout_fn(buf, self.names)
            self._size = len(buf)
            variable = sorted([(4, 12)] + [(off, off + n * dt.itemsize) for off, n, dt in self._layout.values()])
            runs, pos = [], 0
            for a, b in variable:
                if a > pos:
                    runs.append((pos, a, bytes(buf[pos:a])))
                pos = max(pos, b)
            if pos < len(buf):
                runs.append((pos, len(buf), bytes(buf[pos:])))
            self._const = tuple(runs)
        return fields(buf, self._layout)

    def layout(self):
        """The layout of the last message: ``(size, runs, offsets)``: its size in bytes, the byte runs
        outside the numeric fields and stamp as ``(offset, bytes)``, and ``{field: offset}`` (for a
        compiled reader of the same messages, e.g. tsc_controller's StateMap.set_cdr_layout)."""
        if self._layout is None:
            raise ValueError("no message read yet")
        return (self._size, [(a, c) for a, _, c in self._const],
                {k: off for k, (off, _, _) in self._layout.items()})


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
