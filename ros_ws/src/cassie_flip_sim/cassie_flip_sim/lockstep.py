"""Lean rclpy transport for the 2 kHz lockstep: a wait set over a node's subscriptions, no executor.

The simulator and the controller exchange one state and one command per 0.5 ms step. An rclpy
executor costs several hundred microseconds per round trip on this machine kind
(docs/architecture.md); a wait set re-armed before every wait and ``take_message`` on the ready
subscriptions does not. The wait-set API is rclpy's private ``_rclpy`` binding, pinned with rclpy
7.1.6 and covered by the node tests.

Subscriptions used here must belong to a node that no executor spins (otherwise the executor
would take their messages first); their callbacks are never called.
"""
from __future__ import annotations

import time

from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile,
                       ReliabilityPolicy)
from rclpy.signals import SignalHandlerGuardCondition

#: state and command topics: newest only, no retransmission (a lost message is re-sent on timeout)
STREAM_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                        reliability=ReliabilityPolicy.BEST_EFFORT,
                        durability=DurabilityPolicy.VOLATILE)
#: events, references, robot description: every message, and a late joiner still gets them
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _ignore(_msg):
    return None


class SubscriptionSet:
    """Subscriptions polled through one rclpy wait set.

    ``wait(timeout_s)`` blocks until at least one subscription has data (or the timeout, or
    SIGINT) and returns the list of ``(topic, message)`` taken, in subscription order.
    """

    def __init__(self, node, subscriptions):
        """``subscriptions``: list of ``(msg_type, topic, qos)``."""
        self._node = node
        self._subs = [node.create_subscription(t, topic, _ignore, qos)
                      for t, topic, qos in subscriptions]
        self._topics = [topic for _, topic, _ in subscriptions]
        self._sigint = SignalHandlerGuardCondition(context=node.context)
        self._wait_set = _rclpy.WaitSet(len(self._subs), 1, 0, 0, 0, 0, node.context.handle)
        self.interrupted = False

    def subscription(self, topic):
        return self._subs[self._topics.index(topic)]

    def take_all(self):
        """Every message already queued, without waiting."""
        out = []
        for topic, sub in zip(self._topics, self._subs):
            while True:
                got = sub.handle.take_message(sub.msg_type, sub.raw)
                if got is None:
                    break
                out.append((topic, got[0]))
        return out

    def wait(self, timeout_s):
        ws = self._wait_set
        ws.clear_entities()
        for sub in self._subs:
            ws.add_subscription(sub.handle)
        ws.add_guard_condition(self._sigint.handle)
        ws.wait(int(timeout_s * 1e9) if timeout_s is not None and timeout_s >= 0 else -1)
        if ws.get_ready_entities('guard_condition'):
            self.interrupted = True
            return []
        ready = set(ws.get_ready_entities('subscription'))
        out = []
        for topic, sub in zip(self._topics, self._subs):
            if sub.handle.pointer in ready:
                while True:
                    got = sub.handle.take_message(sub.msg_type, sub.raw)
                    if got is None:
                        break
                    out.append((topic, got[0]))
        return out

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
