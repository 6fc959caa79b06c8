"""The live view without ROS (flip_tools.live, flip_tools.live_client): its arguments, which topics
it reads, and the Foxglove WebSocket server as a client sees it — CDR channels with ros2msg
schemas, the bytes forwarded untouched, latched messages for a client that subscribes late."""
import argparse
import re
import socket
import subprocess
import sys
import time

import pytest

from ros_harness import FLIP
from flip_tools.live import (LiveServer, LiveTopics, TopicInfo, live_node_cmd, parse_serving_line,
                             port_arg, port_problem)
from flip_tools.live_client import LiveClient, parse_binary
from flip_tools.typestore import flip_typestore


def flip(*args):
    return subprocess.run([sys.executable, str(FLIP), *args], capture_output=True, text=True, timeout=120)


@pytest.fixture
def bound_port():
    """A port some other program listens on (127.0.0.1)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        yield s.getsockname()[1]


# --- arguments ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("text, port", [("0", 0), ("8765", 8765), ("65535", 65535)])
def test_a_port_is_0_to_65535(text, port):
    assert port_arg(text) == port


@pytest.mark.parametrize("text", ["-1", "65536", "99999", "http", "87.5"])
def test_anything_else_is_refused(text):
    with pytest.raises(argparse.ArgumentTypeError):
        port_arg(text)


@pytest.mark.parametrize("args", [["run", "backflip", "--live", "--live-port", "70000"],
                                  ["stand", "--duration", "1", "--live", "--live-port", "-5"],
                                  ["sim", "--duration", "1", "--live-port", "port"]])
def test_a_port_out_of_range_is_a_usage_error(tmp_path, args):
    out = tmp_path / "run"
    r = flip(*args, "--out", str(out))
    assert r.returncode == 2 and "--live-port" in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert not out.exists()


def test_a_port_in_use_is_refused_before_anything_starts(tmp_path, bound_port):
    """The documented choice: an unusable --live-port is refused like a bad argument (exit 2, the
    reason, nothing started or written), not discovered after the graph is up."""
    assert "already in use" in port_problem(bound_port)
    out = tmp_path / "run"
    r = flip("stand", "--duration", "1", "--live", "--live-port", str(bound_port), "--out", str(out))
    assert r.returncode == 2, r.stdout + r.stderr
    assert f"--live-port {bound_port}: cannot listen on 127.0.0.1:{bound_port} (already in use)" in r.stderr
    assert "ROS_DOMAIN_ID" not in r.stderr and not out.exists()        # no graph, no output folder


def test_a_free_port_and_port_0_are_usable():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        free = s.getsockname()[1]
    assert port_problem(free) is None and port_problem(0) is None


def test_the_node_command_and_its_serving_line():
    assert live_node_cmd(0)[-5:] == ["-m", "flip_tools.live_node", "--port", "0", "--hold-streams"]
    assert live_node_cmd(9, "/bin/stand-in -x") == ["/bin/stand-in", "-x", "--port", "9", "--hold-streams"]
    assert parse_serving_line("starting\nlive: serving ws://127.0.0.1:41234\n{...}") == 41234
    assert parse_serving_line("live: cannot listen on 127.0.0.1:8765 (...)") is None


# --- which topics are read ----------------------------------------------------------------------------
def test_latched_topics_are_always_read_the_others_only_while_watched():
    t = LiveTopics()
    assert t.offer("/robot_description", "std_msgs/msg/String", True, 1).latched == 1
    assert t.offer("/odom", "nav_msgs/msg/Odometry", False, 1).latched == 0
    assert t.offer("/odom", "std_msgs/msg/String", True, 5) is None            # first offer stands
    assert t.offer("/parameter_events", "rcl_interfaces/msg/ParameterEvent", False, 10) is None
    assert t.wanted(set()) == {"/robot_description"}
    assert t.wanted({"/odom", "/not_offered"}) == {"/robot_description", "/odom"}
    # before the graph runs (flip's --hold-streams), a client's wish reads no stream yet; once it
    # runs, /clock is read whoever watches (the sim time of the log times)
    assert t.wanted({"/odom"}, streams=False) == {"/robot_description"}
    t.offer("/clock", "rosgraph_msgs/msg/Clock", False, 1)
    assert t.wanted(set()) == {"/robot_description", "/clock"}
    assert t.wanted(set(), streams=False) == {"/robot_description"}


# --- the server, as a WebSocket client sees it ------------------------------------------------------
def cdr(msgtype, **fields):
    ts = flip_typestore()
    return bytes(ts.serialize_cdr(ts.types[msgtype](**fields), msgtype))


def odometry(z):
    ts = flip_typestore()
    T = ts.types
    return cdr("nav_msgs/msg/Odometry",
               header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=1, nanosec=5), frame_id="world"),
               child_frame_id="pelvis",
               pose=T["geometry_msgs/msg/PoseWithCovariance"](
                   pose=T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=z),
                                                    orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)),
                   covariance=__import__("numpy").zeros(36)),
               twist=T["geometry_msgs/msg/TwistWithCovariance"](
                   twist=T["geometry_msgs/msg/Twist"](linear=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                                                      angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)),
                   covariance=__import__("numpy").zeros(36)))


@pytest.fixture
def server():
    s = LiveServer(0)
    s.add_channel(TopicInfo("/robot_description", "std_msgs/msg/String", 1, True))
    s.add_channel(TopicInfo("/odom", "nav_msgs/msg/Odometry", 0, False))
    yield s
    s.close()


def wait_subscribed(server, topic, n=1):
    for _ in range(200):                # the SDK tells the server on its own thread
        if topic in server.subscribed():
            return
        time.sleep(0.01)
    raise AssertionError(f"no subscription to {topic} reached the server")


def test_channels_are_cdr_with_the_full_ros2msg_definition(server):
    with LiveClient(server.url) as c:
        assert c.subprotocol == "foxglove.sdk.v1"
        ch = c.wait_for_channels(["/odom", "/robot_description"], 10)
    text, _ = flip_typestore().generate_msgdef("nav_msgs/msg/Odometry", ros_version=2)
    assert ch["/odom"]["encoding"] == "cdr" and ch["/odom"]["schemaEncoding"] == "ros2msg"
    assert ch["/odom"]["schemaName"] == "nav_msgs/msg/Odometry" and ch["/odom"]["schema"] == text
    assert "MSG: geometry_msgs/PoseWithCovariance" in text        # every nested definition, concatenated


def test_a_client_offering_only_the_old_protocol_name_is_refused(server):
    """foxglove-sdk speaks the protocol as "foxglove.sdk.v1" only (the Foxglove app offers both)."""
    with pytest.raises(Exception, match="400"):
        LiveClient(server.url, subprotocols=["foxglove.websocket.v1"])


def test_messages_go_out_as_the_bytes_received_and_only_to_subscribers(server):
    with LiveClient(server.url) as c:
        c.wait_for_channels(["/odom"], 10)
        server.forward("/odom", odometry(0.5), 111)             # nobody subscribed: not sent
        sid = next(iter(c.subscribe(["/odom"])))
        wait_subscribed(server, "/odom")
        raw = odometry(0.9)
        server.forward("/odom", raw, 222)
        got = [next(c.messages(10))[1]]
    assert [(m.subscription, m.log_time, m.payload) for m in got] == [(sid, 222, raw)]
    msg = flip_typestore().deserialize_cdr(got[0].payload, "nav_msgs/msg/Odometry")
    assert msg.pose.pose.position.z == 0.9 and msg.child_frame_id == "pelvis"


def test_a_late_client_gets_the_latched_messages(server):
    urdf = cdr("std_msgs/msg/String", data="<robot name='late'/>")
    server.forward("/robot_description", urdf, 333)           # published before anyone connected
    with LiveClient(server.url) as c:
        c.wait_for_channels(["/robot_description"], 10)
        c.subscribe(["/robot_description"])
        wait_subscribed(server, "/robot_description")
        assert server.replay_latched(444) == 1                 # stamped now, as a late ROS subscriber gets it
        got = [next(c.messages(10))[1]]
    assert [(m.log_time, m.payload) for m in got] == [(444, urdf)]
    assert server.replay_latched(555) == 0                    # once per new subscription


def test_the_stamp_of_a_per_step_message():
    from flip_tools.live import header_stamp_ns
    assert header_stamp_ns(odometry(0.5)) == 1_000_000_005
    assert header_stamp_ns(b"\x00\x01\x00\x00") is None


def test_a_re_sent_state_is_forwarded_once_and_each_topic_in_order():
    from flip_tools.live import NewSteps
    steps = NewSteps()
    # sim_node sends step 0's state three times while the graph matches, then steps on
    got = [(t, ns) for t, ns in [("/odom", 0), ("/odom", 0), ("/clock", 0), ("/odom", 0), ("/odom", 5),
                                 ("/clock", 5), ("/odom", 5), ("/odom", 10), ("/odom", 5)] if steps.fresh(t, ns)]
    assert got == [("/odom", 0), ("/clock", 0), ("/odom", 5), ("/clock", 5), ("/odom", 10)]


def test_binary_frames_other_than_messages_are_not_messages():
    assert parse_binary(bytes([0x02]) + (5).to_bytes(8, "little")) is None       # server time
    m = parse_binary(bytes([0x01]) + (7).to_bytes(4, "little") + (9).to_bytes(8, "little") + b"abc")
    assert (m.subscription, m.log_time, m.payload) == (7, 9, b"abc")


# --- the Foxglove layout (docs/foxglove_layout.json) ---------------------------------------------------
LAYOUT = FLIP.parents[1] / "docs" / "foxglove_layout.json"
NUMERIC = {"float32", "float64", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"}


def resolve(path):
    """The ROS type at the end of a Foxglove message path "/topic.field.sub[i]" of a recorded topic:
    ("base", 'float64') or ("msg", 'pkg/msg/Name'); AssertionError when a field does not exist."""
    from flip_tools.rosenv import CONTRACT_TOPICS
    topic, _, rest = path.partition(".")
    assert topic in CONTRACT_TOPICS, f"{path}: {topic} is not a recorded topic"
    store, kind, typ = flip_typestore(), "msg", CONTRACT_TOPICS[topic].msgtype
    for part in rest.split(".") if rest else []:
        name, _, index = part.partition("[")
        assert kind == "msg", f"{path}: {name} of a {typ}"
        fields = dict(store.fielddefs[typ][1])
        assert name in fields, f"{path}: {typ} has no field {name} (it has {sorted(fields)})"
        node, desc = fields[name]
        if index:
            assert node.name in ("SEQUENCE", "ARRAY"), f"{path}: {name} is not an array"
            node, desc = desc[0]
        kind, typ = ("base", desc[0]) if node.name == "BASE" else ("msg", desc)
    return kind, typ


def test_the_layout_shows_fields_the_recorded_topics_have():
    import json
    from cassie_model.robot_params import MOTOR_NAMES
    from cassie_flip_sim.simulator import Simulator
    doc = json.loads(LAYOUT.read_text())
    config = doc["configById"]

    def panels(node):
        return [node] if isinstance(node, str) else panels(node["first"]) + panels(node["second"])
    assert sorted(panels(doc["layout"])) == sorted(config)                  # every panel placed, once
    plotted = [s["value"] for k, c in config.items() if k.split("!")[0] in ("Plot", "StateTransitions")
               for s in c["paths"]]
    # a user script's output: its inputs are recorded topics with the fields it reads
    scripted = [p for p in plotted if p.startswith("/foxglove_script/")]
    scripts = {re.search(r'output = "([^"]+)"', n["sourceCode"]).group(1): n["sourceCode"]
               for n in doc["userNodes"].values()}
    for p in scripted:
        topic, field = p.split(".", 1)
        code = scripts[topic]
        assert re.search(rf"\b{field}\b", code.split("return", 1)[1]), (p, "not in the script's output")
        for inp in re.search(r"inputs = \[([^\]]*)\]", code).group(1).replace('"', "").split(","):
            for axis in "xyz":
                assert resolve(f"{inp.strip()}.wrench.force.{axis}")[1] in NUMERIC
    plotted = [p for p in plotted if p not in scripted]
    assert plotted and all(resolve(p)[0] == "base" and resolve(p)[1] in NUMERIC for p in plotted), plotted
    # the indexed entries are the flywheel's: /joint_states' order is the simulator's, /motor_command's
    # the motor order of docs/architecture.md
    joints = Simulator().joint_names
    assert "/joint_states.velocity[26]" in plotted and joints[26] == "flywheel"
    assert "/motor_command.effort[10]" in plotted and MOTOR_NAMES[10] == "flywheel"
    assert resolve(config["RawMessages!plan"]["topicPath"]) == ("msg", "flip_msgs/msg/FlipReference")
    three_d = config["3D!robot"]
    assert all(resolve(t)[0] == "msg" for t in three_d["topics"]) and "/robot_description" in three_d["topics"]
    assert (three_d["followTf"], three_d["layers"]["grid"]["frameId"]) == ("pelvis", "world")   # /odom's frames
