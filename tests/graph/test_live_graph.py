"""`--live` on a real graph (`flip stand`): a Foxglove WebSocket client (the `websockets` package)
gets every channel the recorder records advertised, subscribes to /odom and decodes the message
frames as nav_msgs/Odometry, and, subscribing late, still gets the latched URDF and /tf_static; a
live view that fails or dies leaves the run going, with a clear message."""
import json
import re
import signal
import subprocess
import sys
import threading

import numpy as np
import pytest

from ros_harness import FLIP, NODES_DIR
from flip_tools.live_client import LiveClient
from flip_tools.rosenv import CONTRACT_TOPICS
from flip_tools.typestore import flip_typestore

LIVE_LINE = re.compile(r"live: (ws://127\.0\.0\.1:(\d+)) — open it in Foxglove")


def start_flip(*args):
    """flip in the background; its output (stdout and stderr) collected by a thread once the live
    line has been read. Returns (process, url, lines)."""
    p = subprocess.Popen([sys.executable, str(FLIP), *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         text=True)
    lines, url = [], None
    for line in p.stdout:
        lines.append(line)
        m = LIVE_LINE.search(line)
        if m:
            url = m.group(1)
            break
    reader = threading.Thread(target=lambda: lines.extend(p.stdout), daemon=True)
    reader.start()
    p.reader = reader
    return p, url, lines


def finish(p, lines, timeout=300):
    rc = p.wait(timeout)
    p.reader.join(10)
    return rc, "".join(lines)


def test_a_client_gets_the_graph_topics_as_cdr_and_latched_ones_late(tmp_path):
    out = tmp_path / "stand"
    # a long stand, stopped by the test once it has seen what it needs (Ctrl-C: exit 130)
    p, url, lines = start_flip("stand", "--duration", "120", "--live", "--live-port", "0", "--out", str(out))
    try:
        assert url is not None, "".join(lines)
        ts = flip_typestore()
        with LiveClient(url) as c:
            assert c.subprotocol == "foxglove.sdk.v1"
            channels = c.wait_for_channels(list(CONTRACT_TOPICS), 120)     # every topic the recorder records
            for topic, ch in channels.items():
                assert (ch["encoding"], ch["schemaEncoding"], ch["schemaName"]) == \
                    ("cdr", "ros2msg", CONTRACT_TOPICS[topic].msgtype), ch
            c.subscribe(["/odom"])
            odom, log_times = [], []
            for topic, m in c.messages(120):
                assert topic == "/odom"
                odom.append(ts.deserialize_cdr(m.payload, "nav_msgs/msg/Odometry"))
                log_times.append(m.log_time)
                if len(odom) == 200:
                    break
            assert len(odom) == 200
            assert {(o.header.frame_id, o.child_frame_id) for o in odom} == {("world", "pelvis")}
            stamps = np.array([o.header.stamp.sec * 10**9 + o.header.stamp.nanosec for o in odom])
            assert np.all(np.diff(stamps) > 0)                                # the simulation's steps, in order
            assert np.all(stamps % 5_000_000 == 0)                           # on the 200 Hz grid of sim time
            assert log_times == stamps.tolist()                               # log time = sim time
            assert 0.8 < np.median([o.pose.pose.position.z for o in odom]) < 1.2   # the pelvis, standing
            # late: the URDF and the fixed joints were published (latched) long before this subscription
            c.subscribe(["/robot_description", "/tf_static"])
            late = {}
            for topic, m in c.messages(60):
                if topic != "/odom":
                    late[topic] = m.payload
                if len(late) == 2:
                    break
        urdf = ts.deserialize_cdr(late["/robot_description"], "std_msgs/msg/String").data
        assert urdf.lstrip().startswith("<robot") and "flywheel" in urdf
        assert len(ts.deserialize_cdr(late["/tf_static"], "tf2_msgs/msg/TFMessage").transforms) > 0
    finally:
        p.send_signal(signal.SIGINT)
        rc, text = finish(p, lines)
    assert rc == 130, text                                                  # interrupted, as asked
    run = json.loads((out / "run.json").read_text())
    assert run["live"]["url"] == url
    live = json.loads((out / "summary.json").read_text())["processes"]["live"]
    assert live["returncode"] == 0 and live["stopped_by"] == "SIGINT", live
    log = (out / "logs" / "live.log").read_text()
    assert "live: the graph runs" in log and "/odom" in log     # released by flip; its count of forwarded messages


@pytest.mark.parametrize("stand_in, message", [
    ([sys.executable, "-c", "raise(SystemExit(3))"], "live view failed, the run goes on without it"),
    ([sys.executable, str(NODES_DIR / "dying_live_node.py")], "live view stopped (exit 7), the run goes on"),
], ids=["fails-to-start", "dies-during-the-run"])
def test_a_live_view_that_fails_or_dies_leaves_the_run_going(tmp_path, stand_in, message):
    out = tmp_path / "stand"
    r = subprocess.run([sys.executable, str(FLIP), "stand", "--duration", "1", "--live", "--live-port", "0",
                        "--exe", "live=" + " ".join(stand_in), "--out", str(out)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr                           # the robot stood: the run's verdict
    assert message in r.stderr, r.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "standing" and summary["topics"]["/odom"] > 0
    assert summary["processes"]["live"]["returncode"] != 0
    assert {n: p["returncode"] for n, p in summary["processes"].items() if n != "live"} == \
        {"recorder": 0, "state": 0, "tsc": 0, "sim": 0}
