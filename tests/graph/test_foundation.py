"""Foundation tests: process harness, flip_msgs between processes, the bag recorder, the planner
node's refusals, `flip run` end to end. Node processes here are the stand-ins under tests/nodes/
(test fixtures); the summary verdict on synthetic bags is tests/unit/test_summary_verdict.py."""
from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ros_harness import FLIP, REPO, stand_in

from flip_msgs.msg import ContactEvent, FlipReference, MotorCommand
from flip_msgs.srv import RequestFlip
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

MOTORS = ["left_hip_roll", "left_hip_yaw", "left_hip_pitch", "left_knee", "left_foot",
          "right_hip_roll", "right_hip_yaw", "right_hip_pitch", "right_knee", "right_foot", "flywheel"]
BEST_EFFORT = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)


def latched(depth):
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


# ---------------------------------------------------------------------------------------------
# (a) two real node processes pass a flip_msgs message; a RequestFlip call is answered
def test_flip_msgs_between_processes_and_service(ros_graph):
    ros_graph.start("source", stand_in("source_node.py"), node_name="source_node")
    ros_graph.start("echo", stand_in("echo_node.py"), node_name="echo_node")
    ros_graph.start("planner", stand_in("fake_planner_node.py"), node_name="planner_node")
    tn = ros_graph.test_node
    echoed = tn.collect(MotorCommand, "/motor_command_echo", QoSProfile(depth=10))
    ros_graph.wait_ready(nodes=["source_node", "echo_node", "planner_node"], services=["/request_flip"],
                         topics={"/motor_command": (1, 1), "/motor_command_echo": (1, 1)})

    tn.spin_until(lambda: len(echoed) >= 3, what="3 MotorCommands relayed source -> echo -> test")
    m = echoed[-1]
    assert list(m.name) == MOTORS
    assert list(m.effort) == pytest.approx([0.5 * i for i in range(11)])
    assert m.compute_time_us >= 3.0          # set by the echo process: it went through it
    assert m.step >= 2 and m.header.stamp.nanosec == 1000 * m.step

    resp = tn.call(RequestFlip, "/request_flip",
                   RequestFlip.Request(kind=RequestFlip.Request.BACKFLIP, apex_height=0.5))
    assert resp.accepted, resp.reason
    assert resp.reason == "" and resp.plan_id == 1 and resp.flight_time > 0
    assert resp.liftoff_pitch_rate < 0          # backflip: negative pitch about +y
    # teardown (fixture): SIGINT to every process, each must exit 0, nothing left behind


# the real tsc_node: its `controller` parameter (ControllerConfig fields as JSON) is checked when it
# starts; a bad one stops it with exit 2 and the reason, not a traceback
def test_tsc_node_refuses_bad_controller_settings(ros_graph):
    import time
    tsc = str(Path(sys.executable).parent / "tsc_node")
    ros_graph.expected_exit["tsc"] = {2}
    p = ros_graph.start("tsc", [tsc], params={"controller": '{"no_such": 1}'})
    deadline = time.monotonic() + 60.0
    while p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    assert p.returncode == 2
    log = (ros_graph.log_dir / "tsc.log").read_text()
    assert "unknown controller setting 'no_such'" in log and "Traceback" not in log


# (d) the real planner_node: a RequestFlip with NaN, a negative apex or an unknown kind gets
# accepted=false with a reason, and the node keeps serving (a valid request is then accepted).
def test_request_flip_rejects_invalid_and_keeps_serving(ros_graph):
    planner = str(Path(sys.executable).parent / "planner_node")
    # the somersault robot: the published robot's backflip is rejected (its flywheel cannot turn the
    # body in the flight; the reason says so, below)
    ros_graph.start("planner", [planner, "--ros-args", "-p", "motor_speed_scale:=3.0", "-p",
                                "flywheel_torque:=260.0"], node_name="planner_node")
    ros_graph.wait_ready(nodes=["planner_node"], services=["/request_flip"])
    tn = ros_graph.test_node
    publish_odom(tn)                                  # the robot stands at its start
    R = RequestFlip.Request
    bad = {"NaN apex": R(kind=R.BACKFLIP, apex_height=float("nan")),
           "negative apex": R(kind=R.FRONTFLIP, apex_height=-0.1),
           "unknown kind": R(kind=99),
           "unreachable apex": R(kind=R.BACKFLIP, apex_height=6.0)}
    for what, req in bad.items():
        r = tn.call(RequestFlip, "/request_flip", req)
        assert not r.accepted and r.reason, what
    assert "apex" in tn.call(RequestFlip, "/request_flip", bad["unreachable apex"]).reason
    wide = tn.call(RequestFlip, "/request_flip", R(kind=R.BACKFLIP, apex_height=1.3, forward_distance=2.5))
    assert not wide.accepted and "binding" in wide.reason, wide.reason
    ok = tn.call(RequestFlip, "/request_flip", R(kind=R.BACKFLIP, apex_height=1.3))
    assert ok.accepted, ok.reason
    assert ok.plan_id == 1 and ok.flight_time > 0 and ok.liftoff_pitch_rate < 0
    # a second request while that flip is under way is refused cleanly
    again = tn.call(RequestFlip, "/request_flip", R(kind=R.FRONTFLIP))
    assert not again.accepted and "under way" in again.reason


def publish_odom(tn, x=0.0, z=None, pitch=0.0) -> dict:
    """/odom of a pelvis at (x, z) pitched by ``pitch``, at rest, published every 5 ms by the test
    node while it spins (e.g. waiting for a service's answer); z None: the standing pose's height.
    Returns the pose, which the caller may change."""
    from fslip_planner.plan import _Robot
    from nav_msgs.msg import Odometry
    pose = {"x": x, "z": float(_Robot.get("I").pelvis0[2]) if z is None else z, "pitch": pitch}
    pub = tn.node.create_publisher(Odometry, "/odom", BEST_EFFORT)

    def publish():
        m = Odometry()
        m.pose.pose.position.x, m.pose.pose.position.z = pose["x"], pose["z"]
        m.pose.pose.orientation.y, m.pose.pose.orientation.w = math.sin(pose["pitch"] / 2), math.cos(pose["pitch"] / 2)
        pub.publish(m)
    tn.node.create_timer(0.005, publish)
    return pose


def test_planner_node_plans_from_the_measured_standing_state(ros_graph):
    """The real planner_node reads the newest /odom at each request: none -> refused (no_state), a
    fallen pelvis -> refused (not_standing), standing still with the flywheel spinning -> refused
    (not_standing), a simulated robot with another flywheel -> refused (robot_mismatch), standing 0.16 m ahead of the start -> a JUMPING reference whose COM targets
    start there (issue 26, items 1 and 5)."""
    from fslip_planner.plan import _Robot
    planner = str(Path(sys.executable).parent / "planner_node")
    ros_graph.start("planner", [planner, "--ros-args", "-p", "motor_speed_scale:=3.0", "-p",
                                "flywheel_torque:=260.0"], node_name="planner_node")
    ros_graph.wait_ready(nodes=["planner_node"], services=["/request_flip"])
    tn = ros_graph.test_node
    R = RequestFlip.Request
    none = tn.call(RequestFlip, "/request_flip", R(kind=R.HOP), timeout=60)
    assert not none.accepted and none.reason.startswith("no_state:"), none.reason

    robot = _Robot.get("I", 3.0, 260.0)
    pose = publish_odom(tn, x=0.0, z=0.25, pitch=math.radians(88))      # lying on its back
    refs = tn.collect(FlipReference, "/fslip/reference", latched(5))
    fallen = tn.call(RequestFlip, "/request_flip", R(kind=R.HOP), timeout=60)
    assert not fallen.accepted and fallen.reason.startswith("not_standing:"), fallen.reason
    assert "tilted 88.0 deg" in fallen.reason

    pose.update(x=0.16, z=float(robot.pelvis0[2]), pitch=0.0)
    # standing still, its flywheel still spinning (a landing taking its momentum out): refused too
    from sensor_msgs.msg import JointState
    js_pub = tn.node.create_publisher(JointState, "/joint_states", 10)
    wheel = {"speed": -300.0}
    tn.node.create_timer(0.005, lambda: js_pub.publish(JointState(name=["flywheel"], position=[0.0],
                                                                  velocity=[wheel["speed"]], effort=[0.0])))
    spinning = tn.call(RequestFlip, "/request_flip", R(kind=R.HOP), timeout=60)
    assert not spinning.accepted and spinning.reason.startswith("not_standing:"), spinning.reason
    assert "flywheel spinning at 2865 rpm" in spinning.reason, spinning.reason

    wheel["speed"] = 0.0
    # a simulator with another flywheel than the planner's (its /robot_description_mjcf): refused, named
    from cassie_model.model import export_mjcf
    from flip_transport.lockstep import LATCHED_QOS
    from std_msgs.msg import String
    desc = tn.node.create_publisher(String, "/robot_description_mjcf", LATCHED_QOS)
    desc.publish(String(data=export_mjcf("III")))
    tn.spin_for(1.0)                                  # the planner takes the description before the request
    other = tn.call(RequestFlip, "/request_flip", R(kind=R.HOP), timeout=60)
    assert not other.accepted and other.reason.startswith("robot_mismatch:"), other.reason
    assert "28.63 kg" in other.reason and "flywheel I " in other.reason, other.reason
    desc.publish(String(data=export_mjcf("I")))
    tn.spin_for(1.0)                                  # the planner takes the new description
    ok = tn.call(RequestFlip, "/request_flip", R(kind=R.HOP), timeout=120)
    assert ok.accepted, ok.reason
    tn.spin_until(lambda: refs, what="the JUMPING reference")
    ref = refs[-1]
    x_com = np.asarray(ref.value).reshape(len(ref.t), len(ref.output_names))[:, ref.output_names.index("x_com")]
    assert x_com[0] == pytest.approx(0.16 + robot.com_in_pelvis[0], abs=1e-9)


# ---------------------------------------------------------------------------------------------
def test_launcher_children_take_sigint_when_the_launcher_ignores_it(tmp_path):
    """A launcher started in the background by a non-interactive shell inherits SIGINT ignored; its
    nodes must still stop on SIGINT (the first step of the stop sequence), not need SIGTERM."""
    code = ("import signal; signal.signal(signal.SIGINT, signal.SIG_IGN); "
            "from flip_tools.launcher import Launcher; "
            f"L = Launcher(0, log_dir={str(tmp_path)!r}); L.start('polite', ['sleep', '600']); "
            "rc = L.stop('polite', sigint_timeout=5.0, sigterm_timeout=5.0); "
            "print(rc, L.procs['polite'].stopped_by)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [str(-signal.SIGINT), "SIGINT"], r.stdout


# ---------------------------------------------------------------------------------------------
def test_interrupt_inside_a_destructor_still_stops_the_wait(tmp_path):
    """A SIGINT whose handler runs inside a `__del__` has its exception swallowed by Python
    ("Exception ignored in ..."); the wait loops must still end with Interrupted, not run on."""
    code = f"""
import os, signal, sys, time
from flip_tools.launcher import GraphWatcher, Interrupted, interrupt_latch

class SignalsOnDelete:
    def __del__(self):
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.01)   # the handler runs here, inside __del__

w = GraphWatcher(domain_id=0)
for wait in (lambda: w.wait_until("never", lambda: False, timeout=20),
             lambda: w.spin_until(lambda: False, timeout=20)):
    interrupt_latch.arm()
    SignalsOnDelete()
    try:
        wait()
        print("no-interrupt")
    except Interrupted as e:
        print(e)
    interrupt_latch.hold()
    interrupt_latch.disarm()
w.close()
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "Exception ignored" in r.stderr          # the handler's own exception was lost ...
    assert r.stdout.split() == ["SIGINT", "SIGINT"], r.stdout + r.stderr   # ... yet both waits ended with it


# ---------------------------------------------------------------------------------------------
def test_launcher_escalates_and_leaves_nothing_behind(ros_graph):
    """A process that ignores SIGINT gets SIGTERM; one that ignores both gets SIGKILL; a
    grandchild in the process group is killed too."""
    py = sys.executable
    ignore_int = ("import signal,time; signal.signal(signal.SIGINT, signal.SIG_IGN); print('ready', flush=True);"
                  "time.sleep(600)")
    ignore_all = ("import signal,time,subprocess; [signal.signal(s, signal.SIG_IGN) for s in "
                  "(signal.SIGINT, signal.SIGTERM)]; subprocess.Popen(['sleep','600']); print('ready', flush=True);"
                  "time.sleep(600)")
    L = ros_graph.launcher
    L.start("stubborn", [py, "-c", ignore_int])
    L.start("deaf", [py, "-c", ignore_all])
    L.start("polite", ["sleep", "600"])
    for name in ("stubborn", "deaf"):   # signal handlers installed (not a sleep: wait for the line)
        ros_graph.test_node.spin_until(lambda: "ready" in L.procs[name].log_text(), what=f"{name} ready")
    rc1 = L.stop("stubborn", sigint_timeout=0.5, sigterm_timeout=5)
    rc2 = L.stop("deaf", sigint_timeout=0.5, sigterm_timeout=0.5)
    rc3 = L.stop("polite")
    assert (rc1, L.procs["stubborn"].stopped_by) == (-signal.SIGTERM, "SIGTERM")
    assert (rc2, L.procs["deaf"].stopped_by) == (-signal.SIGKILL, "SIGKILL")
    assert (rc3, L.procs["polite"].stopped_by) == (-signal.SIGINT, "SIGINT")
    assert L.leftovers() == []
    ros_graph.expected_exit.update(stubborn={-signal.SIGTERM}, deaf={-signal.SIGKILL}, polite={-signal.SIGINT})


# ---------------------------------------------------------------------------------------------
# (b) `flip record` writes an MCAP rosbag2 that rosbags reads back with the custom types
def test_record_writes_mcap_with_custom_types(ros_graph, tmp_path):
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    out = tmp_path / "rec"
    topics = ["/motor_command", "/contact_events", "/fslip/reference", "/robot_description",
              "/robot_description_mjcf", "/chatter"]
    ros_graph.start("recorder", [sys.executable, str(FLIP), "record", *topics, "--out", str(out)])
    tn = ros_graph.test_node
    status = tn.collect(String, "/flip_recorder/status", QoSProfile(depth=10))
    # the contract topics are subscribed at start-up (types and QoS from docs/architecture.md)
    ros_graph.wait_ready(nodes=["flip_recorder"],
                         topics={t: (0, 1) for t in topics if t != "/chatter"})

    n = tn.node
    p_cmd = n.create_publisher(MotorCommand, "/motor_command", BEST_EFFORT)
    p_ev = n.create_publisher(ContactEvent, "/contact_events", latched(10))
    p_ref = n.create_publisher(FlipReference, "/fslip/reference", latched(5))
    p_desc = n.create_publisher(String, "/robot_description", latched(1))
    p_mjcf = n.create_publisher(String, "/robot_description_mjcf", latched(1))
    p_chat = n.create_publisher(String, "/chatter", 10)   # not in the contract: type+QoS from the graph
    pubs = [p_cmd, p_ev, p_ref, p_desc, p_mjcf, p_chat]
    tn.spin_until(lambda: all(p.get_subscription_count() >= 1 for p in pubs), what="recorder matched")

    for i in range(5):
        p_cmd.publish(MotorCommand(step=100 + i, name=MOTORS, effort=[float(i)] * 11, compute_time_us=50.0 + i))
    for ev in (ContactEvent.LIFT_OFF, ContactEvent.TOUCH_DOWN):
        e = ContactEvent(step=7 + ev, event=ev, domain=2 + ev, centroidal_pitch_momentum=-31.5)
        e.pelvis_pose.position.z = 1.25
        p_ev.publish(e)
    ref = FlipReference(plan_id=3, domain=FlipReference.DOMAIN_FLIGHT, t=[0.0, 0.1, 0.2],
                        output_names=["H_pitch", "L"], value=[1.0, 0.9, 2.0, 0.95, 3.0, 1.0],
                        d_value=[0.0] * 6, dd_value=[0.0] * 6, parameter_names=["T1"], parameter_values=[0.3],
                        flight_time=0.55, rotation_to_go=-2 * math.pi, solve_time=0.8, iterations=42)
    p_ref.publish(ref)
    p_desc.publish(String(data="<robot name='cassie'/>"))
    p_mjcf.publish(String(data="<mujoco model='cassie'/>"))
    for i in range(3):
        p_chat.publish(String(data=f"hello {i}"))

    expect = {"/motor_command": 5, "/contact_events": 2, "/fslip/reference": 1, "/robot_description": 1,
              "/robot_description_mjcf": 1, "/chatter": 3}

    def recorded_all():
        if not status:
            return False
        counts = json.loads(status[-1].data)["counts"]
        return all(counts.get(t, 0) >= k for t, k in expect.items())
    # best effort may drop on a loaded machine: resend MotorCommands until the recorder has 5
    def wait_cmds():
        counts = json.loads(status[-1].data)["counts"] if status else {}
        if counts.get("/motor_command", 0) < 5:
            p_cmd.publish(MotorCommand(step=200, name=MOTORS, effort=[9.0] * 11, compute_time_us=1.0))
        return recorded_all()
    tn.spin_until(wait_cmds, timeout=30, what=f"recorder status reaching {expect}")

    rc = ros_graph.launcher.stop("recorder")
    assert rc == 0, ros_graph.launcher.procs["recorder"].log_tail()

    bag = out / "bag"
    assert (bag / "metadata.yaml").exists()
    assert list(bag.glob("*.mcap")), list(bag.iterdir())
    assert "storage_identifier: mcap" in (bag / "metadata.yaml").read_text()

    # read back with a typestore built ONLY from the definitions stored in the bag
    with Reader(bag) as reader:
        store = get_typestore(Stores.ROS2_JAZZY)
        defs = {}
        for c in reader.connections:
            if c.msgtype.startswith("flip_msgs/"):
                assert "std_msgs/Header header" in c.msgdef.data and "MSG: std_msgs/Header" in c.msgdef.data
                defs.update(get_types_from_msg(c.msgdef.data, c.msgtype))
        store.register(defs)
        types = {c.topic: c.msgtype for c in reader.connections}
        qos = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
        got: dict[str, list] = {}
        for c, t, raw in reader.messages():
            got.setdefault(c.topic, []).append((t, store.deserialize_cdr(raw, c.msgtype)))
    assert types["/motor_command"] == "flip_msgs/msg/MotorCommand"
    assert types["/chatter"] == "std_msgs/msg/String"
    assert qos["/contact_events"][0].durability.name == "TRANSIENT_LOCAL"
    assert qos["/motor_command"][0].reliability.name == "BEST_EFFORT"
    for t, k in expect.items():
        assert len(got[t]) >= k, (t, len(got[t]))

    cmds = [m for _, m in got["/motor_command"] if m.step >= 100 and m.step < 200]
    assert [m.step for m in cmds] == sorted(m.step for m in cmds)
    assert all(list(m.name) == MOTORS and len(m.effort) == 11 for m in cmds)
    assert {m.step for m in cmds} <= set(range(100, 105))
    evs = [m for _, m in got["/contact_events"]]
    assert [e.event for e in evs] == [ContactEvent.LIFT_OFF, ContactEvent.TOUCH_DOWN]
    assert evs[0].pelvis_pose.position.z == 1.25 and evs[1].centroidal_pitch_momentum == -31.5
    r = got["/fslip/reference"][0][1]
    assert (r.plan_id, r.domain, list(r.output_names), r.iterations) == (3, 2, ["H_pitch", "L"], 42)
    assert np.allclose(r.value, ref.value) and r.rotation_to_go == pytest.approx(-2 * math.pi)
    assert got["/robot_description"][0][1].data == "<robot name='cassie'/>"
    assert got["/robot_description_mjcf"][0][1].data == "<mujoco model='cassie'/>"
    assert [m.data for _, m in got["/chatter"]] == ["hello 0", "hello 1", "hello 2"]
    # log time is the wall-clock receive time (ns since the epoch, within this test's lifetime)
    import time
    for t, _ in got["/chatter"]:
        assert abs(t * 1e-9 - time.time()) < 600

    # and the project's reader gives arrays
    from flip_tools.bag import load_bag
    data = load_bag(bag)
    assert data["/motor_command"]["effort"].shape[1] == 11
    assert data["/fslip/reference"]["refs"][0]["value"].shape == (3, 2)
    assert list(data["/contact_events"]["event"]) == [0, 1]


# ---------------------------------------------------------------------------------------------
# `flip request` and `flip run` end to end, against the stand-in nodes
def _stand_in_exes() -> list[str]:
    py = sys.executable
    nodes = REPO / "tests" / "nodes"
    return ["--exe", f"sim={py} {nodes / 'fake_sim_node.py'}",
            "--exe", f"planner={py} {nodes / 'fake_planner_node.py'}",
            "--exe", f"tsc={py} {nodes / 'fake_tsc_node.py'}"]


def _live_processes_of_domain(domain: int) -> list[str]:
    """Processes of this repo still running in a ROS domain (via /proc/<pid>/environ)."""
    left = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            env = (d / "environ").read_bytes().split(b"\0")
            cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            stat = (d / "stat").read_text()
        except OSError:
            continue
        if stat[stat.rfind(")") + 2] == "Z":
            continue
        if f"ROS_DOMAIN_ID={domain}".encode() in env and str(REPO) in cmd:
            left.append(f"{d.name}: {cmd}")
    return left


def test_flip_request_cli(ros_graph):
    ros_graph.start("planner", stand_in("fake_planner_node.py"))
    ros_graph.wait_ready(nodes=["planner_node"], services=["/request_flip"])
    base = [sys.executable, str(FLIP), "request", "--domain", str(ros_graph.domain_id), "--timeout", "60"]
    r = subprocess.run(base + ["frontflip", "--apex", "0.5"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    resp = json.loads(r.stdout)
    assert resp["accepted"] is True and resp["plan_id"] == 1 and resp["liftoff_pitch_rate"] > 0
    r = subprocess.run(base + ["backflip", "--apex", "5"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 4 and json.loads(r.stdout)["reason"]      # rejected


def test_flip_run_end_to_end_with_stand_ins(tmp_path):
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, str(FLIP), "run", "backflip", "--out", str(out), "--distance", "0.3",
                        *_stand_in_exes()], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["outcome"] == "landed" and s["net_rotation_deg"] == pytest.approx(-360, abs=1)
    assert s["response"]["accepted"] is True
    assert {n: p["returncode"] for n, p in s["processes"].items()} == {"recorder": 0, "state": 0, "sim": 0,
                                                                      "planner": 0, "tsc": 0}
    # the tool ends the run at the planned end (touch-down + settle) and stops the sim there
    assert s["processes"]["sim"]["stopped_by"] == "SIGINT"
    run = json.loads((out / "run.json").read_text())
    # the tool's log says how the run ended (end reached, the sim's own duration, a stall).  The sim time
    # the tool stopped at, not the bag's: the stand-in simulator publishes best-effort on a wall-clock
    # timer, without waiting for the recorder, so a loaded machine's bag may lack its last steps
    end = run["end_sim_time"]
    assert end - 0.001 <= run["stop_sim_time"] <= end + 0.5, r.stdout + r.stderr
    assert s["sim_duration_s"] <= run["stop_sim_time"] + 0.5
    assert s["topics"]["/fslip/reference"] == 3 and s["topics"]["/contact_events"] == 2
    assert (out / "bag" / "metadata.yaml").exists() and (out / "fig6.png").exists()
    assert run["sim_params"]["mode"] == "lockstep" and run["sim_params"]["scenario"] == "flat"
    assert _live_processes_of_domain(run["ros_domain_id"]) == []
    # flip holds /dev/cpu_dma_latency at 0 us where it may (flip_tools.cpu_latency), and says which
    lat = run["cpu_dma_latency"]
    assert lat["requested_us"] == 0 and isinstance(lat["held"], bool)
    assert ("previous_us" in lat) if lat["held"] else lat["reason"]
    # the pinned simulator and controller run SCHED_BATCH in lockstep (flip_transport.lockstep)
    assert run["lockstep_sched"] == "batch"


def test_flip_run_rejected_and_interrupted(tmp_path):
    # rejected request: exit 4, reason printed, everything stopped
    out = tmp_path / "rej"
    r = subprocess.run([sys.executable, str(FLIP), "run", "frontflip", "--apex", "5", "--out", str(out),
                        *_stand_in_exes()], capture_output=True, text=True, timeout=300)
    assert r.returncode == 4, r.stdout + r.stderr
    assert "request rejected: apex_height" in r.stdout
    assert "plots failed" not in r.stdout + r.stderr          # a stand-in's bag plots, without its scene
    s = json.loads((out / "summary.json").read_text())
    assert s["outcome"] == "rejected"
    assert {"fig6.png", "pelvis.png"} <= set(s["plots"])
    assert all(p["returncode"] == 0 for p in s["processes"].values()), s["processes"]
    dom = json.loads((out / "run.json").read_text())["ros_domain_id"]
    assert _live_processes_of_domain(dom) == []

    # Ctrl-C in the middle of a run: exit 130, every node stopped, the bag closed and readable
    out = tmp_path / "int"
    p = subprocess.Popen([sys.executable, str(FLIP), "run", "frontflip", "--out", str(out), "--duration", "1000",
                          *_stand_in_exes()], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        for line in p.stderr:
            if "accepted (plan" in line:
                break
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 130
    assert "plots failed" not in err
    s = json.loads((out / "summary.json").read_text())
    assert s["topics"]["/clock"] > 0
    assert all(r["returncode"] == 0 for r in s["processes"].values()), s["processes"]
    dom = json.loads((out / "run.json").read_text())["ros_domain_id"]
    assert _live_processes_of_domain(dom) == []
