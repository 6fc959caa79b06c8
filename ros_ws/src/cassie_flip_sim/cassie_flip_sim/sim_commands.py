"""The commands and references sim_node takes: the serialized motor commands read per step, the
planner's references noted, the waits for step k's command (rclpy's, or rcl's C API through
``_rcl_io.CommandWait``) with the state re-sent while the controller is silent, and the lockstep's
hold for the planner's reference at a contact event (:class:`SimCommands`, a part of
:class:`sim_node.SimNode`)."""
from __future__ import annotations

import struct
import time

from flip_msgs.msg import FlipReference
from flip_transport.lockstep import (PLANNER_HOLD_TIMEOUT_S, holds_for_reference,  # noqa: F401
                                     reference_answers, stamp_to_ns)

#: realtime mode: steps without a fresh command before the motors go to damping (20 ms)
WATCHDOG_STEPS = 40
#: wall time without a command before the state is sent again and the silence is reported
COMMAND_RESEND_S = 0.05


class SimCommands:
    """SimNode's commands and references in."""

    def _note_reference(self, msg):
        self.plan_in_force = (msg.plan_id, msg.domain, stamp_to_ns(msg.start_time))
        if self.plant is not None and msg.domain == FlipReference.DOMAIN_JUMPING:
            self.plant.jump_started(stamp_to_ns(msg.start_time) * 1e-9)

    def _commands(self, taken):
        """``(step, torques)`` of the serialized commands taken; references are noted."""
        out = []
        for topic, msg in taken:
            if topic == '/fslip/reference':
                self._note_reference(msg)
                continue
            try:
                f = self.read_command(msg)
            except (ValueError, IndexError, struct.error):       # not a MotorCommand's CDR
                self.malformed_commands += 1
                continue
            out.append((int(f['step'][0]), f['effort']))
        return out

    def _handle_incoming(self, taken, k):
        """Sort taken messages; return the torques for step k if they came."""
        u = None
        for step, effort in self._commands(taken):
            if step == k and len(effort) == 11:
                u = effort
            elif step == k:
                self._wrong_size(k, len(effort))
        return u

    def _wrong_size(self, k, n):
        self.node.get_logger().error(f'/motor_command for step {k} has {n} torques, not 11: ignored')

    def _newest_command(self, taken, k):
        """Realtime mode: the torques of the newest well-formed command answering a recent step
        (≤ k)."""
        best = None
        for step, effort in self._commands(taken):
            if len(effort) == 11 and k - WATCHDOG_STEPS <= step <= k and (best is None or step > best[0]):
                best = (step, effort)
        return None if best is None else best[1]

    def _hold_for_reference(self, k, domain):
        """Lockstep: wait until the planner's reference for ``domain`` (start ≥ now) is seen."""
        if not holds_for_reference(self.plan_in_force):
            return
        t0 = time.monotonic()
        now_ns = k * self.dt_ns
        while time.monotonic() - t0 < PLANNER_HOLD_TIMEOUT_S:
            if reference_answers(self.plan_in_force, domain, now_ns, self.dt_ns):
                break
            self._handle_incoming(self.subs.wait(0.1), -1)
            if self.subs.interrupted or not self._running():
                return
        else:
            self.node.get_logger().warn(
                f'no reference for domain {domain} within {PLANNER_HOLD_TIMEOUT_S} s: continuing')
        self.hold_times.append(time.monotonic() - t0)
        self.node.get_logger().info(f'held {1e3 * self.hold_times[-1]:.1f} ms for the planner')

    def _take_references(self):
        sub = self.subs.subscription('/fslip/reference')
        while (got := sub.handle.take_message(sub.msg_type, sub.raw)) is not None:
            self._note_reference(got[0])

    def _wait_command(self, k):
        if self.command_wait is not None:
            return self._wait_command_rcl(k)
        t_sent = time.monotonic()
        warned = False
        while True:
            cmd = self._handle_incoming(self.subs.wait(COMMAND_RESEND_S), k)
            if cmd is not None:
                return cmd
            if self.subs.interrupted or not self._running():
                return None
            if time.monotonic() - t_sent >= COMMAND_RESEND_S:
                warned = self._send_again(k, time.monotonic() - t_sent, warned)

    def _send_again(self, k, silent_s, warned):
        """No command for step k within COMMAND_RESEND_S: send the state again (and serve the
        services), warn once the controller has been silent for a second. Returns whether it has."""
        self.resends += 1
        if not warned and silent_s > 1.0:
            self.node.get_logger().warn(f'controller silent for step {k}: waiting')
            warned = True
        self._publish_state(k)
        self.executor.spin_once(timeout_sec=0.0)
        return warned

    def _wait_command_rcl(self, k, status=None, t_first=None):
        """_wait_command through _rcl_io.CommandWait: the torques of step k (a view of the command
        buffer), or None when interrupted. ``status``, ``t_first``: of a first wait already made (by
        the compiled loop) and when (time.monotonic) it began."""
        cw, u = self.command_wait, self._u_in
        t_first = t_sent = time.monotonic() if t_first is None else t_first
        warned = False
        while True:
            if status is None:
                left = COMMAND_RESEND_S - (time.monotonic() - t_sent)
                status = cw.wait(k, max(int(left * 1e9), 0), u)
            if status == cw.GOT:
                return u
            if status == cw.INTERRUPTED or not self._running():
                self.subs.interrupted = True
                return None
            if status == cw.REFERENCE:
                self._take_references()
            elif status == cw.WRONG_SIZE:
                self._wrong_size(k, cw.last_count)
            else:                                          # TIMEOUT
                warned = self._send_again(k, time.monotonic() - t_first, warned)
                t_sent = time.monotonic()
            status = None
