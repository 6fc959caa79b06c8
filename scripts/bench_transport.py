#!/usr/bin/env python3
"""The lockstep's floor without a simulator: two processes on one CPU trade the simulator's per-step
messages over rclpy as sim_node and tsc_node do (flip_transport.lockstep: raw serialized messages,
a wait set, best-effort depth 1), and the answering one does nothing, busy work, or the real
controller tick (``Controller.compute`` on recorded standing states, replayed in a loop).  Prints a
table: round trip per step, the real-time factor that would give at 2 kHz, CPU time per step of each
process's main thread and its middleware threads, and the answering side's work per step.

The state side publishes ``/odom`` and ``/joint_states`` (33 joints, as sim_node) and waits for the
``/motor_command`` of that step (re-sending after 50 ms); the command side wakes on
``/joint_states``, takes both, works, answers.  ``--io rcl`` (default) does that through rcl's C API
as the nodes do by default (``flip_transport._rcl_io``), ``--io python`` through rclpy
(``lockstep.SubscriptionSet``).  Anything the real graph adds (MuJoCo's step, the state's
conversion, the recorder's copies) comes on top of these rows.

    .venv/bin/python scripts/bench_transport.py [--steps 6000] [--work-us 150] [--io rcl|python]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

WARMUP = 500
STATE_JOINTS = 33


def _cpu_line(cpu0, n):
    proc = time.process_time() - cpu0[0]
    main = time.thread_time() - cpu0[1]
    return {"main_us": 1e6 * main / n, "other_us": 1e6 * max(proc - main, 0.0) / n}


def _close(waiter, subs, node):
    """The rcl waiter (if any) before the subscriptions it uses, then the node and rclpy."""
    import rclpy
    if waiter is not None:
        waiter.close()
    subs.destroy()
    node.destroy_node()
    rclpy.try_shutdown()


def state_side(steps: int, io: str) -> dict:
    import numpy as np
    import rclpy
    from flip_transport import _rcl_io
    from flip_transport.lockstep import (STREAM_QOS, RawMessage, SubscriptionSet, joint_state_layout,
                                         motor_command_layout, odometry_layout, pin_to_lockstep_cpu,
                                         MessageReader)
    from flip_msgs.msg import MotorCommand
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import JointState
    pin_to_lockstep_cpu()
    rclpy.init()
    node = rclpy.create_node("transport_state")
    from flip_transport.lockstep import LATCHED_QOS
    from flip_msgs.msg import FlipReference
    subs = SubscriptionSet(node, [(MotorCommand, "/motor_command", STREAM_QOS),
                                  (FlipReference, "/fslip/reference", LATCHED_QOS)], raw=("/motor_command",))
    pub_js = node.create_publisher(JointState, "/joint_states", STREAM_QOS)
    pub_od = node.create_publisher(Odometry, "/odom", STREAM_QOS)
    js = RawMessage(JointState(name=[f"joint_{i}" for i in range(STATE_JOINTS)], position=[0.0] * STATE_JOINTS,
                               velocity=[0.0] * STATE_JOINTS, effort=[0.0] * STATE_JOINTS), joint_state_layout)
    odom = Odometry(child_frame_id="pelvis")
    odom.header.frame_id = "world"
    od = RawMessage(odom, odometry_layout)
    read = MessageReader(motor_command_layout)
    deadline = time.monotonic() + 30.0
    while pub_js.get_subscription_count() < 1 or pub_od.get_subscription_count() < 1:
        if time.monotonic() > deadline:
            raise SystemExit("no command side matched within 30 s")
        time.sleep(0.01)
    time.sleep(0.5)
    resends = 0
    if io == "rcl":
        cw = _rcl_io.CommandWait(node.context.handle.pointer, subs.subscription("/motor_command").handle.pointer,
                                 subs.subscription("/fslip/reference").handle.pointer,
                                 subs.sigint_guard.handle.pointer)
        p_od, p_js, u = pub_od.handle.pointer, pub_js.handle.pointer, np.zeros(11)

        def send(ns):
            _rcl_io.publish(p_od, od.buf, ns)
            _rcl_io.publish(p_js, js.buf, ns)

        def answered(k):
            return cw.wait(k, 50_000_000, u) == cw.GOT
    else:
        def send(ns):
            for m in (od, js):
                m.stamp(ns)
            pub_od.publish(od.data())
            pub_js.publish(js.data())

        def answered(k):
            return any(t == "/motor_command" and read(m)["step"][0] == k for t, m in subs.wait(0.05))
    for k in range(steps + WARMUP):
        if k == WARMUP:
            t0, cpu0 = time.perf_counter(), (time.process_time(), time.thread_time())
        send(k * 500_000)
        while not answered(k):
            resends += 1
            send(k * 500_000)
    wall = time.perf_counter() - t0
    _close(cw if io == "rcl" else None, subs, node)
    return {"round_trip_us": 1e6 * wall / steps, "resends": resends, **_cpu_line(cpu0, steps)}


def _standing_ticks(n: int):
    """A controller and n recorded standing states (closed loop with the simulator, one process)."""
    from cassie_model.model import export_mjcf
    from cassie_flip_sim.simulator import Simulator
    from tsc_controller.domains import Controller
    from tsc_controller.state import StateConverter
    sim = Simulator()
    ctl = Controller(export_mjcf())
    conv = StateConverter(ctl.dyn)
    states = []
    for _ in range(n):
        q, v = conv.from_simulator(sim)
        states.append((q, v, sim.time))
        u, _ = ctl.compute(q, v, sim.time)
        sim.step(u)
    return Controller(export_mjcf()), states


def command_side(work: str, work_us: float, io: str) -> dict:
    import rclpy
    from flip_transport import _rcl_io
    from flip_transport.lockstep import (STREAM_QOS, RawMessage, SubscriptionSet, motor_command_layout,
                                         pin_to_lockstep_cpu, read_stamp_ns)
    from flip_msgs.msg import MotorCommand
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import JointState
    ctl = states = None
    if work == "tick":
        ctl, states = _standing_ticks(2000)
    pin_to_lockstep_cpu()
    rclpy.init()
    node = rclpy.create_node("transport_command")
    subs = SubscriptionSet(node, [(JointState, "/joint_states", STREAM_QOS), (Odometry, "/odom", STREAM_QOS)],
                           raw=("/joint_states", "/odom"))
    pub = node.create_publisher(MotorCommand, "/motor_command", STREAM_QOS)
    cmd = RawMessage(MotorCommand(name=[f"motor_{i}" for i in range(11)], effort=[0.0] * 11), motor_command_layout)
    n, busy, cpu0, answered = 0, 0.0, None, -1
    if io == "rcl":
        sw = _rcl_io.StateWait(node.context.handle.pointer, subs.sigint_guard.handle.pointer,
                               subs.subscription("/joint_states").handle.pointer,
                               subs.subscription("/odom").handle.pointer, [])
        p_cmd = pub.handle.pointer

        def next_state(timeout_s):
            return read_stamp_ns(sw.js) if sw.wait(int(timeout_s * 1e9)) & sw.STATE else None

        def answer(ns):
            _rcl_io.publish(p_cmd, cmd.buf, ns)
    else:
        def next_state(timeout_s):
            taken = subs.wait(timeout_s, on=("/joint_states",))
            stamps = [read_stamp_ns(m) for t, m in taken if t == "/joint_states"]
            return max(stamps) if stamps else None

        def answer(ns):
            cmd.stamp(ns)
            pub.publish(cmd.data())
    while rclpy.ok():
        ns = next_state(30.0 if cpu0 is None else 2.0)
        if ns is None:
            break
        if ns == answered:                         # a re-sent state: the same answer
            answer(ns)
            continue
        k = ns // 500_000
        if k == WARMUP:
            cpu0, n, busy = (time.process_time(), time.thread_time()), 0, 0.0
        t0 = time.perf_counter()
        if ctl is not None:
            q, v, t = states[k % len(states)]
            ctl.compute(q, v, t)
        while time.perf_counter() - t0 < work_us * 1e-6:
            pass
        busy += time.perf_counter() - t0
        cmd.fields["step"][0] = k
        answer(ns)
        answered = ns
        n += 1
    out = {"work_us": 1e6 * busy / max(n, 1), **_cpu_line(cpu0, max(n, 1))} if cpu0 else {}
    _close(sw if io == "rcl" else None, subs, node)
    return out


def one(work: str, work_us: float, steps: int, io: str) -> dict:
    """Both sides as processes of their own in a domain of their own, pinned to one CPU."""
    from flip_tools.launcher import PROFILES_ENV, fastdds_profile_file
    from flip_tools.rosenv import claim_domain, node_env
    cpu = sorted(os.sched_getaffinity(0))[-1]
    with claim_domain() as dom:
        # as the launcher starts the graph's nodes: its Fast DDS profile, one CPU for both
        env = node_env(dom.domain_id, {"FLIP_LOCKSTEP_CPU": cpu,
                                       PROFILES_ENV: os.environ.get(PROFILES_ENV) or fastdds_profile_file()})
        me = [sys.executable, __file__]
        cmd_side = subprocess.Popen(me + ["--role", "command", "--work", work, "--work-us", str(work_us),
                                          "--io", io], env=env, stdout=subprocess.PIPE, text=True)
        state = subprocess.run(me + ["--role", "state", "--steps", str(steps), "--io", io], env=env,
                               stdout=subprocess.PIPE, text=True, timeout=600)
        c_out = cmd_side.communicate(timeout=60)[0]
    s, c = json.loads(state.stdout.strip().splitlines()[-1]), json.loads(c_out.strip().splitlines()[-1])
    return {"state": s, "command": c}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=6000)
    ap.add_argument("--work-us", type=float, default=150.0, help="busy work of the 'busy' row, us")
    ap.add_argument("--io", default="rcl", choices=["rcl", "python"],
                    help="per-step messages through rcl's C API (as the nodes by default) or rclpy")
    ap.add_argument("--role", choices=["state", "command"], help=argparse.SUPPRESS)
    ap.add_argument("--work", default="none", choices=["none", "busy", "tick"], help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.role == "state":
        print(json.dumps(state_side(a.steps, a.io)))
        return 0
    if a.role == "command":
        print(json.dumps(command_side(a.work, a.work_us if a.work == "busy" else 0.0, a.io)))
        return 0
    rows = [("no work", "none"), (f"busy loop {a.work_us:g} us", "busy"), ("controller tick (standing states)", "tick")]
    print(f"two processes on one CPU, /odom + /joint_states -> /motor_command per step, {a.steps} steps, "
          f"{'rcl C API' if a.io == 'rcl' else 'rclpy'}")
    print("| answering side does | round trip us | RTF at 2 kHz | state main / other us | command main / other us "
          "| its work us | re-sent |")
    print("|---|---|---|---|---|---|---|")
    for label, work in rows:
        r = one(work, a.work_us, a.steps, a.io)
        s, c = r["state"], r["command"]
        print(f"| {label} | {s['round_trip_us']:.1f} | {500.0 / s['round_trip_us']:.2f} | "
              f"{s['main_us']:.0f} / {s['other_us']:.0f} | {c['main_us']:.0f} / {c['other_us']:.0f} | "
              f"{c['work_us']:.0f} | {s['resends']} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
