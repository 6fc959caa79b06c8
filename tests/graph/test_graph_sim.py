"""`flip sim` through the real sim_node (lockstep, zero torques), recorded: /clock on the 0.5 ms step
grid, /joint_states with the flywheel, /odom; two runs record the same messages (log times aside)."""
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ros_harness import FLIP


def record(tmp_path, name):
    from flip_tools.bag import load_bag
    out = tmp_path / name
    r = subprocess.run([sys.executable, str(FLIP), "sim", "--duration", "1.0", "--out", str(out)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    return load_bag(out / "bag", ["/clock", "/joint_states", "/odom"])


def test_flip_sim_records_the_contract_topics_and_is_deterministic(tmp_path):
    a, b = record(tmp_path, "a"), record(tmp_path, "b")
    clk = a["/clock"]["sim_t"]
    steps = np.diff(clk) / 0.0005                                        # whole 0.5 ms steps
    assert np.allclose(steps, np.round(steps), atol=1e-6) and np.round(steps).min() >= 1
    assert "flywheel" in a["/joint_states"]["names"]
    for topic, keys in (("/joint_states", ("pos", "vel", "eff")), ("/odom", ("pos", "quat", "lin", "ang"))):
        # the recorder is best-effort and niced: a sim running freely (no controller) outpaces it
        # on a loaded machine and steps are lost (summary.json reports the recorded fraction);
        # the steps both bags hold must be the same to the bit
        ta, tb = a[topic]["t"], b[topic]["t"]
        common, ia, ib = np.intersect1d(ta, tb, return_indices=True)
        assert len(common) >= 100
        for k in keys:
            np.testing.assert_array_equal(a[topic][k][ia], b[topic][k][ib])
    assert a["/odom"]["pos"][-1, 2] < a["/odom"]["pos"][0, 2]          # sinking under zero torque


@pytest.mark.parametrize("sim_io, compiled", [(True, True), (True, False), (False, False)],
                         ids=["rcl-compiled-loop", "rcl-python-loop", "python"])
def test_lockstep_simulator_ignores_bad_commands_and_resends(ros_graph, sim_io, compiled):
    """sim_node in lockstep against a controller that answers one step with 2 torques, then with
    bytes that are no MotorCommand, then with an answer to an earlier step: each is ignored (the
    wrong size and the garbage with a log line) and the state sent again, the third re-send's answer
    is taken and the run ends after all its steps (rcl's C API and rclpy alike; with rcl, the
    compiled loop hands the wrong size and the time-outs back to the Python loop, which answers them
    as its own)."""
    from ros_harness import python_node_cmd, NODES_DIR
    from flip_tools.launcher import ros_args
    ros_graph.start("controller", python_node_cmd(NODES_DIR / "awkward_controller_node.py"), node_name="tsc_node")
    ros_graph.start("sim", [str(Path(sys.executable).parent / "sim_node")]
                    + ros_args(params={"duration": 0.005, "rcl_io": sim_io, "compiled_loop": compiled}),
                    node_name="sim_node")
    r = ros_graph.launcher.wait_exit("sim", 120)
    log = (ros_graph.log_dir / "sim.log").read_text()
    assert r == 0, log
    assert ("; compiled loop;" in log) == compiled, log
    assert "/motor_command for step 3 has 2 torques, not 11: ignored" in log
    assert "1 /motor_command messages that are not MotorCommand CDR ignored" in log
    m = re.search(r"done: (\d+) steps.*state re-sent (\d+) times", log)
    assert m and int(m.group(1)) == 10 and int(m.group(2)) >= 3, log


def test_a_held_lockstep_simulator_sends_nothing_before_its_release(ros_graph):
    """sim_node in lockstep with ``hold:=true`` (as `flip` starts it): with every subscriber there it
    still sends no state and no /clock until /sim/release is called (`flip` calls it once the
    recorder reports its side of every per-step topic matched: a bag lost the first 0.29 s of
    /joint_states when the simulator started on its own subscription counts), then runs its steps."""
    import time
    from flip_tools.launcher import ros_args
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock
    from std_srvs.srv import Trigger
    tn = ros_graph.test_node
    clock = tn.collect(Clock, "/clock", QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT))
    ros_graph.start("sim", [str(Path(sys.executable).parent / "sim_node")]
                    + ros_args(params={"controller": "none", "duration": 0.01, "hold": True,
                                       "min_subscribers": 0}), node_name="sim_node")
    t_end = time.monotonic() + 3.0
    tn.spin_until(lambda: time.monotonic() > t_end, timeout=10, what="3 s held")
    assert clock == [] and ros_graph.launcher.procs["sim"].poll() is None
    assert "held before step 0 until /sim/release" in (ros_graph.log_dir / "sim.log").read_text()
    r = tn.call(Trigger, "/sim/release", Trigger.Request(), timeout=30)
    assert r.success and r.message == "released: lockstep from step 0"
    assert ros_graph.launcher.wait_exit("sim", 60) == 0
    tn.spin_until(lambda: len(clock) > 0, timeout=10, what="/clock after the release")
    assert "done: 20 steps" in (ros_graph.log_dir / "sim.log").read_text()


def test_realtime_stand_runs_on_the_wall_clock_and_counts_late_commands(tmp_path):
    """`flip stand --mode realtime`: the simulator holds the robot at step 0 until the tool has seen
    the recorder match every topic and calls /sim/release (a reader matching the controller's
    publisher mid-run stalled the controller's state for ~0.3 s, and the robot fell), then steps on
    the wall clock with the newest command and counts its late steps and the steps without a new
    command; the robot stands, both nodes end cleanly and the bag holds the run."""
    import json
    out = tmp_path / "rt"
    r = subprocess.run([sys.executable, str(FLIP), "stand", "--mode", "realtime", "--duration", "1.0",
                        "--out", str(out)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["topics"]["/odom"] > 0 and s["topics"]["/motor_command"] > 0, s
    assert {p["returncode"] for p in s["processes"].values()} == {0}, s["processes"]
    log = (out / "logs" / "sim.log").read_text()
    m = re.search(r"done: (\d+) steps, 1\.000 s sim in ([0-9.]+) s wall.*realtime: (\d+) late steps, "
                  r"(\d+) steps without a new command", log)
    assert m and int(m.group(1)) == 2000 and float(m.group(2)) >= 0.99 and int(m.group(4)) < 2000, log
    # on the wall clock the nodes keep the kernel's default policy (woken threads preempt)
    assert json.loads((out / "run.json").read_text())["lockstep_sched"] == "other"
    assert "running: mode=realtime" in log and "SCHED_OTHER" in log and "SCHED_BATCH" not in log
    assert "held at step 0 for" in log and "released: on the wall clock" in r.stdout + r.stderr


def test_stand_records_each_foots_wrench_on_the_clock_grid_carrying_the_weight(tmp_path):
    """`flip stand` through the real nodes: /left_foot/wrench and /right_foot/wrench
    (geometry_msgs/WrenchStamped in the foot links' frames) are in the bag for every 10th step
    (200 Hz of sim time, the steps of /clock: none lost), stamped with the step's sim time; in world
    axes (the foot links' poses from the bag's URDF and state, as /tf gives them) the two forces sum
    to the robot's weight, m·g with m from the model (~420 N), once it has settled."""
    from cassie_flip_sim.foot_wrench import FOOT_LINKS, WRENCH_TOPICS
    from cassie_flip_sim.simulator import Simulator
    from flip_tools.bag import NOT_SUMMARIZED, load_bag
    from flip_tools.measured import foot_wrenches_world, robot_mass
    out = tmp_path / "stand"
    r = subprocess.run([sys.executable, str(FLIP), "stand", "--duration", "2.5", "--out", str(out)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    bag = load_bag(out / "bag", exclude=NOT_SUMMARIZED)
    steps = np.arange(0, 5000, 10)
    for topic, link in zip(WRENCH_TOPICS, FOOT_LINKS):
        assert bag.topics[topic]["type"] == "geometry_msgs/msg/WrenchStamped"
        w = bag[topic]
        assert w["frame_id"] == link
        assert np.array_equal(np.round(w["t"] / 0.0005), steps), topic
        assert np.allclose(w["t"] / 0.0005, np.round(w["t"] / 0.0005), atol=1e-6)
    assert "foot wrenches every 10 steps" in (out / "logs" / "sim.log").read_text()
    world = foot_wrenches_world(bag)
    assert world is not None and np.array_equal(np.round(world["t"] / 0.0005), steps)
    mass = Simulator().total_mass()
    assert robot_mass(bag) == mass
    fz = world["force"][:, :, 2]
    late = world["t"] >= 1.5
    np.testing.assert_allclose(fz[late].sum(axis=1), mass * 9.81, rtol=0.02)
    assert np.all(fz[late] > 0.4 * mass * 9.81)                        # on both feet
    assert np.abs(world["force"][late, :, :2].sum(axis=1)).max() < 0.02 * mass * 9.81
