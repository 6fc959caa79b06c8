"""The lean lockstep transport (flip_transport.lockstep): serialized-message layouts against
rclpy's own (de)serialisation, and `flip stand` (sim_node <-> tsc_node in lockstep, recorded):
every step's /odom and /joint_states (and /clock at its 200 Hz) in the bag even when the recorder stalls (SIGSTOP)
for half a second, log times = wall-clock receive times, and two runs with the controller in the
loop give the same states to the bit."""
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from flip_transport.lockstep import (MessageReader, RawMessage, fields, joint_state_layout,
                                     motor_command_layout, odometry_layout, read_stamp_ns)
from flip_msgs.msg import MotorCommand
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from ros_harness import FLIP


_PIN_PROBE = """
import os, threading
from flip_transport.lockstep import pin_to_lockstep_cpu, scheduling_note
cpu = pin_to_lockstep_cpu()
seen = {}
t = threading.Thread(target=lambda: seen.update(later=os.sched_getscheduler(0)))   # made after the pin
t.start(); t.join()
print(cpu, os.sched_getscheduler(0), seen["later"], int(os.SCHED_BATCH), int(os.SCHED_OTHER), scheduling_note())
"""


def _pin_probe(cpu, sched):
    env = {**os.environ, "FLIP_LOCKSTEP_CPU": cpu, "FLIP_LOCKSTEP_SCHED": sched}
    return subprocess.run([sys.executable, "-c", _PIN_PROBE], env=env, capture_output=True, text=True,
                          timeout=60)


def test_pin_to_lockstep_cpu_sets_the_policy_for_every_thread():
    """FLIP_LOCKSTEP_SCHED=batch: the pinned process and a thread it starts later (as rclpy.init's DDS
    threads are) run SCHED_BATCH on the one CPU; unset leaves the default policy; an unknown name is
    refused with the variable named; no pinning (empty CPU) leaves the policy alone."""
    cpu = str(min(os.sched_getaffinity(0)))
    r = _pin_probe(cpu, "batch")
    got, main, later, batch, other = r.stdout.split()[:5]
    assert r.returncode == 0 and got == cpu and main == later == batch, r.stdout + r.stderr
    assert r.stdout.rstrip().endswith(f"cpus [{cpu}], SCHED_BATCH")
    r = _pin_probe(cpu, "")
    got, main, later, batch, other = r.stdout.split()[:5]
    assert r.returncode == 0 and main == later == other and "SCHED_OTHER" in r.stdout, r.stdout + r.stderr
    r = _pin_probe(cpu, "fifo")
    assert r.returncode != 0 and "FLIP_LOCKSTEP_SCHED='fifo'" in r.stderr, r.stderr
    r = _pin_probe("", "batch")
    assert r.returncode == 0 and r.stdout.split()[:3] == ["None", other, other], r.stdout + r.stderr


@pytest.mark.parametrize("names, n_vel", [(["a"], 0), (["left_hip_roll", "bb", "ccc"], 3),
                                          ([f"joint_{i}" for i in range(33)], 33)])
def test_joint_state_layout_reads_what_rclpy_wrote(names, n_vel):
    rng = np.random.default_rng(len(names))
    js = JointState(name=names, position=list(rng.normal(size=len(names))),
                    velocity=list(rng.normal(size=n_vel)), effort=list(rng.normal(size=len(names))))
    js.header.frame_id, js.header.stamp.sec, js.header.stamp.nanosec = "abc", 3, 500_000
    buf = serialize_message(js)
    got_names, layout = joint_state_layout(buf)
    assert got_names[0] == names and read_stamp_ns(buf) == 3_000_500_000
    f = fields(buf, layout)
    for k in ("position", "velocity", "effort"):
        np.testing.assert_array_equal(f[k], getattr(js, k))
    assert joint_state_layout(buf, got_names)[0] is got_names      # the name list skipped by a compare


def test_message_reader_keeps_a_layout_while_only_the_numbers_change():
    """A stream from one publisher (a preallocated message patched in place, as the nodes send) keeps
    its first layout; other strings (names, frame id, of the same length or not) get a new one.  (A
    compare that also sees the CDR padding: rclpy's serialisation does not always zero it, which
    only costs a new layout.)"""
    read = MessageReader(motor_command_layout)
    raw = RawMessage(MotorCommand(name=["a", "b"], effort=[0.0, 0.0]), motor_command_layout)
    first = None
    for step, effort in ((7, [1.0, 2.0]), (123_456, [-3.0, 4.5]), (8, [0.5, 0.25])):
        raw.stamp(step * 500_000)
        raw.fields["step"][0], raw.fields["effort"][:] = step, effort
        f = read(raw.data())
        first = first or read._layout
        assert read._layout is first and read.names[0] == ["a", "b"]
        assert list(f["effort"]) == effort and f["step"][0] == step

    def cmd(names, effort, frame):
        m = MotorCommand(name=names, effort=effort, step=9)
        m.header.frame_id = frame
        return bytes(serialize_message(m))
    for names, effort, frame in ((["c", "d"], [5.0, 6.0], ""),            # other names, same length
                                 (["a", "b"], [5.0, 6.0], "w"),           # another frame id
                                 (["a", "bb"], [5.0, 6.0], ""),           # longer
                                 (["a", "b", "c"], [5.0, 6.0, 7.0], "")):  # more
        f = read(cmd(names, effort, frame))
        assert read.names[0] == names and list(f["effort"]) == effort and f["step"][0] == 9


def test_raw_messages_deserialize_as_rclpy_messages():
    odom = Odometry(child_frame_id="pelvis")
    odom.header.frame_id = "world"
    raw = RawMessage(odom, odometry_layout)
    raw.stamp(1_234_567_890_123)
    raw.fields["pose"][:] = [1, 2, 3, 0.1, 0.2, 0.3, 0.9]
    raw.fields["twist"][:] = [4, 5, 6, 7, 8, 9]
    o = deserialize_message(raw.data(), Odometry)
    assert (o.header.stamp.sec, o.header.stamp.nanosec) == (1234, 567_890_123)
    assert (o.header.frame_id, o.child_frame_id) == ("world", "pelvis")
    p, q = o.pose.pose.position, o.pose.pose.orientation
    assert [p.x, p.y, p.z, q.x, q.y, q.z, q.w] == [1, 2, 3, 0.1, 0.2, 0.3, 0.9]
    t = o.twist.twist
    assert [t.linear.x, t.linear.y, t.linear.z, t.angular.x, t.angular.y, t.angular.z] == [4, 5, 6, 7, 8, 9]

    cmd = RawMessage(MotorCommand(name=["m1", "motor_2"], effort=[0.0, 0.0]), motor_command_layout)
    cmd.fields["effort"][:] = [-1.5, 2.5]
    cmd.fields["step"][0] = 123_456_789_012
    cmd.fields["compute_time_us"][0] = 250.5
    m = deserialize_message(cmd.data(), MotorCommand)
    assert (list(m.name), list(m.effort), m.step, m.compute_time_us) == (["m1", "motor_2"], [-1.5, 2.5],
                                                                          123_456_789_012, 250.5)
    names, layout = motor_command_layout(cmd.data())
    assert names[0] == ["m1", "motor_2"] and fields(cmd.data(), layout)["step"][0] == 123_456_789_012

    clock = RawMessage(Clock())
    clock.stamp(2_000_000_500)
    c = deserialize_message(clock.data(), Clock).clock
    assert (c.sec, c.nanosec) == (2, 500)


def test_subscription_set_takes_each_queued_message_once(test_node):
    """SubscriptionSet.wait: every message of a latched (depth 10) topic, in order; the newest of a
    depth-1 stream, once; a topic outside ``on`` taken when another wakes the wait; a message that
    comes after a wait returned is there at the next one."""
    import rclpy
    from flip_transport.lockstep import LATCHED_QOS, STREAM_QOS, SubscriptionSet, wait_for_subscribers
    from std_msgs.msg import String
    node = rclpy.create_node("subscription_set_test", context=test_node.context)
    subs = SubscriptionSet(node, [(String, "/s", STREAM_QOS), (String, "/l", LATCHED_QOS),
                                  (String, "/quiet", LATCHED_QOS)], raw=("/s",))
    pub_s = test_node.node.create_publisher(String, "/s", STREAM_QOS)
    pub_l = test_node.node.create_publisher(String, "/l", LATCHED_QOS)
    try:
        assert wait_for_subscribers(pub_s, timeout_s=10.0) and wait_for_subscribers(pub_l, timeout_s=10.0), \
            "subscriptions did not match"
        time.sleep(0.2)

        def collect(on, until, timeout=5.0):
            got, end = [], time.monotonic() + timeout
            while not until(got) and time.monotonic() < end:
                got += subs.wait(0.1, on=on)
            return got
        for i in range(3):
            pub_l.publish(String(data=f"l{i}"))
        time.sleep(0.2)                        # the latched ones are queued before the stream wakes
        for i in range(3):
            pub_s.publish(String(data=f"s{i}"))
        got = collect(("/s",), lambda g: any(t == "/s" for t, _ in g))
        latched = [m.data for t, m in got if t == "/l"]
        stream = [deserialize_message(m, String).data for t, m in got if t == "/s"]
        assert latched == ["l0", "l1", "l2"]
        assert stream == ["s2"]                                # depth 1: the newest, once
        assert subs.wait(0.05, on=("/s",)) == [] and not subs.interrupted
        pub_l.publish(String(data="l3"))
        got = collect(None, lambda g: len(g) > 0)
        assert [(t, m.data) for t, m in got] == [("/l", "l3")]
    finally:
        subs.destroy()
        node.destroy_node()


def _recorder_pid(out):
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            cmd = open(f"/proc/{pid}/cmdline", "rb").read().split(b"\0")
        except OSError:
            continue
        if b"record" in cmd and str(out / "bag").encode() in cmd:
            return int(pid)
    raise AssertionError(f"no recorder process for {out}")


def _wait_sim_running(p, out):
    """Until the simulator of the `flip` process ``p`` (output DIR ``out``) has started stepping, or
    ``p`` has ended (flip's own graph timeout)."""
    sim_log = out / "logs" / "sim.log"
    while p.poll() is None and not (sim_log.exists() and "running" in sim_log.read_text()):
        time.sleep(0.02)


def stand(tmp_path, name, duration=1.0, stall_recorder_s=0.0, io="rcl", extra=(), ok=(0,),
          topics=("/clock", "/joint_states", "/odom", "/motor_command")):
    """`flip stand`; with ``stall_recorder_s``, the recorder is stopped (SIGSTOP) that long once the
    simulator runs; ``io``: its --io; ``extra``: more of its options; ``ok``: its exit codes that
    pass."""
    from flip_tools.bag import load_bag
    out = tmp_path / name
    p = subprocess.Popen([sys.executable, str(FLIP), "stand", "--duration", str(duration), "--out", str(out),
                          "--io", io, *extra],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if stall_recorder_s:
        _wait_sim_running(p, out)
        pid = _recorder_pid(out)
        os.kill(pid, signal.SIGSTOP)
        time.sleep(stall_recorder_s)
        os.kill(pid, signal.SIGCONT)
    output = p.communicate(timeout=300)[0]
    assert p.returncode in ok, output
    return load_bag(out / "bag", list(topics)), out


def test_lockstep_stand_records_every_step_and_is_deterministic(tmp_path):
    """(The second run's simulator and controller use rclpy for their per-step messages, and so the
    simulator's Python loop, the first run's rcl's C API and the simulator's compiled loop: the same
    states to the bit.)"""
    (a, out_a), (b, _) = stand(tmp_path, "a"), stand(tmp_path, "b", stall_recorder_s=0.5, io="python")
    n = 2000                                                            # 1 s of 0.5 ms steps
    for bag in (a, b):
        steps = {"/odom": bag["/odom"]["t"], "/joint_states": bag["/joint_states"]["t"]}
        for topic, t in steps.items():                                  # none lost (a re-send may repeat one)
            assert np.array_equal(np.unique(np.round(t / 0.0005)), np.arange(n)), topic
        # /clock at 200 Hz (sim_node's clock_rate): every 10th step, and the last one
        clock_steps = np.unique(np.round(bag["/clock"]["sim_t"] / 0.0005))
        assert np.array_equal(clock_steps, np.r_[np.arange(0, n, 10), n - 1]), clock_steps
        if bag.count("/motor_command"):           # (the recorder may match the controller late)
            cmd = bag["/motor_command"]
            assert np.array_equal(cmd["step"], np.round(cmd["t"] / 0.0005))  # each command names its step
        # log time = when the DDS reader got the message, not when the recorder took it (it takes
        # what is queued every 10 ms, so take times would repeat within each batch): steps carry
        # distinct, increasing log times, and the bag shows the rate
        dt_log = np.diff(bag["/odom"]["t_log"])
        assert np.all(dt_log >= 0) and np.count_nonzero(dt_log > 0) > 0.9 * len(dt_log)
    # the simulator's loop per step (its log), as scripts/bench_graph.py reads it
    import importlib.util
    spec = importlib.util.spec_from_file_location("bench_graph", FLIP.parent / "bench_graph.py")
    bench_graph = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench_graph)
    loop = bench_graph.sim_loop_us(out_a / "logs" / "sim.log")
    assert list(loop) == ["simulate", "publish state", "wait for command", "planner holds", "rest"], loop
    # and each node's CPU time per step: the simulator's main thread cannot use more than the loop's wall time
    for role in ("sim", "tsc"):
        cpu = bench_graph.cpu_per_step_us(out_a / "logs" / f"{role}.log")
        assert list(cpu) == ["main thread", "other threads"], (role, cpu)
        assert cpu["main thread"] > 0 and cpu["other threads"] >= 0, (role, cpu)
    assert bench_graph.cpu_per_step_us(out_a / "logs" / "sim.log")["main thread"] <= sum(loop.values()) + 1
    assert loop["simulate"] > 0 and loop["publish state"] > 0 and loop["wait for command"] > 0
    assert loop["planner holds"] == 0 and loop["rest"] >= 0                # standing: nothing to plan
    # both nodes pinned to one CPU as SCHED_BATCH threads (flip's default in lockstep), as the kernel
    # reports it to each
    for role, line in (("sim", "running: mode=lockstep.*; compiled loop"), ("tsc", "controller built")):
        text = (out_a / "logs" / f"{role}.log").read_text()
        assert re.search(line + r".*; cpus \[\d+\], SCHED_BATCH\n", text), (role, text[-2000:])
    for topic, keys in (("/joint_states", ("pos", "vel", "eff")), ("/odom", ("pos", "quat", "lin", "ang"))):
        _, ia = np.unique(a[topic]["t"], return_index=True)
        _, ib = np.unique(b[topic]["t"], return_index=True)
        for k in keys:                                                  # the controller in the loop, bit for bit
            np.testing.assert_array_equal(a[topic][k][ia], b[topic][k][ib])


def test_compiled_sim_loop_records_what_the_python_loop_records(tmp_path):
    """`flip stand` with the simulator's compiled loop (default) and with --sim-loop python (both
    rcl's C API), its controller answering every state at once with zero torques
    (stand_ins/zero_tick_tsc_node.py): the robot falls, so the compiled loop hands back to Python at
    lift-offs, touch-downs and body contacts (its C++ contact detector and body-contact test) as well
    as every 200 steps.  Both record the same run to the bit: every step's /odom, /joint_states and
    /motor_command, /clock, the contact events (steps, kinds, the states they carry), and the feet's
    wrenches every 10th step (the compiled loop publishes them from C++)."""
    from cassie_flip_sim.foot_wrench import WRENCH_TOPICS
    zero_tick = f"tsc={sys.executable} {FLIP.parent / 'stand_ins' / 'zero_tick_tsc_node.py'}"
    topics = ("/clock", "/joint_states", "/odom", "/motor_command", "/contact_events", *WRENCH_TOPICS)
    n = 3000
    runs = {loop: stand(tmp_path, loop, duration=n * 0.0005, ok=(0, 1), topics=topics,
                        extra=["--exe", zero_tick, "--sim-loop", loop, "--cpu-dma-latency", "off"])
            for loop in ("compiled", "python")}
    (a, out_a), (b, out_b) = runs["compiled"], runs["python"]
    assert "; compiled loop;" in (out_a / "logs" / "sim.log").read_text()
    assert "; compiled loop;" not in (out_b / "logs" / "sim.log").read_text()
    for topic, keys in (("/joint_states", ("pos", "vel", "eff")), ("/odom", ("pos", "quat", "lin", "ang")),
                        ("/motor_command", ("step", "effort"))):
        ta, ia = np.unique(a[topic]["t"], return_index=True)
        tb, ib = np.unique(b[topic]["t"], return_index=True)
        if topic != "/motor_command":        # (the recorder may match the controller late)
            assert np.array_equal(np.round(ta / 0.0005), np.arange(n)) and np.array_equal(tb, ta), topic
        common, ja, jb = np.intersect1d(ta, tb, return_indices=True)
        assert len(common) > 0.9 * n, topic
        for k in keys:
            np.testing.assert_array_equal(a[topic][k][ia[ja]], b[topic][k][ib[jb]], err_msg=f"{topic} {k}")
    np.testing.assert_array_equal(a["/clock"]["sim_t"], b["/clock"]["sim_t"])
    for topic in WRENCH_TOPICS:
        assert np.array_equal(np.round(a[topic]["t"] / 0.0005), np.arange(0, n, 10)), topic
        for k in ("t", "force", "torque"):
            np.testing.assert_array_equal(a[topic][k], b[topic][k], err_msg=f"{topic} {k}")
    assert np.abs(a[WRENCH_TOPICS[0]]["force"]).max() > 10.0           # the feet were loaded
    ea, eb = a["/contact_events"], b["/contact_events"]
    assert {0, 1, 2} <= set(ea["event"]), ea["event"]    # lift-off, touch-down, body contact
    for k in ("t", "step", "event", "domain", "frame_id", "pelvis_pos", "pelvis_quat", "com_pos", "com_vel",
              "H_pitch", "left_normal_force", "right_normal_force", "support_center"):
        assert np.array_equal(ea[k], eb[k]), k


def test_bench_graph_names_the_steps_a_bag_misses(tmp_path):
    """bench_graph's recorded column: fractions of the stepped steps per topic, and which steps a
    topic misses ('last' for the final step), from the bag alone."""
    import importlib.util

    from synthetic_bag import write_flip_bag
    spec = importlib.util.spec_from_file_location("bench_graph", FLIP.parent / "bench_graph.py")
    bench_graph = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench_graph)
    kw = dict(dt=0.0005, t_stand=0.2, t_rest=0.1, flight_time=0.3)
    write_flip_bag(tmp_path / "whole", **kw)
    assert bench_graph.recorded_fraction(tmp_path / "whole") == "1.0000/1.0000"
    write_flip_bag(tmp_path / "holes", drop_joint_states=(7, 8, -1), **kw)
    got = bench_graph.recorded_fraction(tmp_path / "holes")
    n = round((0.2 + 0.3 + 0.3 + 0.4 + 0.1) / 0.0005) + 1           # the synthetic run's steps
    assert got == f"1.0000/{(n - 3) / n:.4f} (joint_states 3 missing: 7, 8, last)", got


def test_bench_graph_zero_tick_runs_the_graph_with_an_instant_controller(tmp_path):
    """bench_graph --zero-tick: `flip stand` with the controller node's tick replaced by zero torques
    (scripts/stand_ins/zero_tick_tsc_node.py); every step answered, with zeros, by that node."""
    import importlib.util

    from flip_tools.bag import load_bag
    spec = importlib.util.spec_from_file_location("bench_graph", FLIP.parent / "bench_graph.py")
    bench_graph = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench_graph)
    out = tmp_path / "zero"
    r = bench_graph.one_run("backflip", out, ["--cpu-dma-latency", "off", "--apex", "1.3"], zero_tick_s=0.5)
    assert r["rtf"] and r["rtf"] > 0 and r["cpu"]["tsc"]["main thread"] > 0, r
    cmd = load_bag(out / "bag", ["/motor_command"])["/motor_command"]
    assert np.array_equal(np.unique(cmd["step"]), np.arange(1000))       # 0.5 s: every step answered
    assert not np.any(cmd["effort"])                                        # by the instant controller


def test_bench_graph_versus_runs_pairs_and_compares_them_pair_by_pair():
    """bench_graph --versus: each run a pair, A with the options given and then B with the extra ones
    (here the kernel's default policy instead of SCHED_BATCH), each row named and its policy shown,
    and B's factor against A's pair by pair; paired_line itself on rows of known factors."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("bench_graph", FLIP.parent / "bench_graph.py")
    bench_graph = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench_graph)
    rows = [{"rtf": x} for x in (1.2, 1.3, 1.25, 1.2, 1.1, None)]
    assert bench_graph.paired_line(rows) == ("B against A, pair by pair: +0.100, -0.050; B faster in 1 of 2, "
                                             "median difference +0.025")
    assert bench_graph.paired_line([{"rtf": None}, {"rtf": 1.0}]).endswith("no pair with both factors")
    r = subprocess.run([sys.executable, str(FLIP.parent / "bench_graph.py"), "--runs", "1", "--zero-tick", "0.3",
                        "--cpu-dma-latency", "off", "--versus", "--lockstep-sched other"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    header = [c.strip() for c in next(ln for ln in lines if ln.startswith("| run | outcome |")).split("|")]
    rows = [ln.split("|") for ln in lines if ln.startswith("| 0A |") or ln.startswith("| 0B |")]
    col = header.index("sched")
    assert [(c[1].strip(), c[col].strip()) for c in rows[:2]] == [("0A", "batch"), ("0B", "other")], r.stdout
    assert re.search(r"^B against A, pair by pair: [+-]\d\.\d{3}; B faster in [01] of 1", r.stdout, re.M), r.stdout


def test_a_run_stopped_midway_records_odom_and_joint_states_of_the_same_steps(tmp_path):
    """`flip stand` interrupted while stepping (exit 130): the simulator, stopped by SIGINT mid-loop,
    ends at a step's end: the bag holds /odom and /joint_states of the same steps, no /clock beyond the
    last step, and its log has the run's summary lines.  (With rclpy's signal handlers, which
    shut the context down from another thread at once, a step could publish its /odom and fail its
    /joint_states, and the end of the run was cut short; that happened in ~1 stop of 3 of `flip run`
    here, less often in this test.)"""
    from flip_tools.bag import load_bag
    out = tmp_path / "stopped"
    p = subprocess.Popen([sys.executable, str(FLIP), "stand", "--duration", "60", "--out", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    _wait_sim_running(p, out)
    time.sleep(1.0)
    p.send_signal(signal.SIGINT)
    output = p.communicate(timeout=120)[0]
    assert p.returncode == 130, output
    bag = load_bag(out / "bag", ["/odom", "/joint_states", "/clock"])
    od, js = (np.unique(np.round(bag[t]["t"] / 0.0005)) for t in ("/odom", "/joint_states"))
    assert len(od) > 200 and np.array_equal(od, js), (len(od), len(js), od[-3:], js[-3:])
    # a step publishes its /clock before its state: a clock beyond the last state would be a step cut
    # short.  /clock is best-effort (depth 1): beside another graph the bag lacked the last 10 of them
    assert round(bag["/clock"]["sim_t"][-1] / 0.0005) <= od[-1]
    log = (out / "logs" / "sim.log").read_text()
    assert "done:" in log and "loop per step" in log and "cpu per step" in log, log
