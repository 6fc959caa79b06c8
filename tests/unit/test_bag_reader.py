"""flip_tools.bag: the per-step topics read from their bytes at once give what rosbags'
message-by-message deserialisation gives, to the bit; a topic whose layout changes, or a layout that
reads wrong, goes the message-by-message way."""
from __future__ import annotations

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

from synthetic_bag import write_flip_bag

from flip_tools import bag as B
from flip_tools.typestore import flip_typestore

PER_STEP = {"/clock", "/odom", "/joint_states", "/motor_command"}


def _both(path, monkeypatch):
    """(load_bag as it is, the topics it read at once, load_bag with every topic deserialised)."""
    fast_topics = []
    real = B._fast_arrays

    def spy(msgtype, msgs, store):
        out = real(msgtype, msgs, store)
        if out is not None:
            fast_topics.append(msgtype)
        return out
    monkeypatch.setattr(B, "_fast_arrays", spy)
    fast = B.load_bag(path)
    monkeypatch.setattr(B, "_fast_arrays", lambda *a: None)
    slow = B.load_bag(path)
    monkeypatch.setattr(B, "_fast_arrays", real)
    return fast, fast_topics, slow


def _assert_same(a, b, topics):
    assert a.topics == b.topics
    for topic in topics:
        x, y = a[topic], b[topic]
        assert set(x) == set(y), topic
        for k, v in y.items():
            if isinstance(v, np.ndarray):
                assert x[k].dtype == v.dtype and np.array_equal(x[k], v, equal_nan=True), (topic, k)
            else:
                assert x[k] == v, (topic, k)


def test_per_step_topics_read_at_once_equal_the_deserialised_ones(tmp_path, monkeypatch):
    write_flip_bag(tmp_path / "bag", dt=0.0005, t_stand=0.2, t_rest=0.2, flight_time=0.3)
    fast, fast_types, slow = _both(tmp_path / "bag", monkeypatch)
    assert sorted(fast_types) == sorted(["rosgraph_msgs/msg/Clock", "nav_msgs/msg/Odometry",
                                         "sensor_msgs/msg/JointState", "flip_msgs/msg/MotorCommand"])
    _assert_same(fast, slow, PER_STEP)
    assert fast.count("/odom") > 2000 and fast["/odom"]["frame_id"] == slow["/odom"]["frame_id"]


def _joint_state_bag(path, names_per_message, effort=True):
    store = flip_typestore()
    T = store.types
    JS, Header, Time = T["sensor_msgs/msg/JointState"], T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        for i, names in enumerate(names_per_message):
            n = len(names)
            msg = JS(header=Header(stamp=Time(sec=i, nanosec=5), frame_id=""), name=list(names),
                     position=np.arange(n) + 0.5 * i, velocity=-np.arange(n) - 0.25 * i,
                     effort=np.ones(n) * i if effort else np.zeros(0))
            w.write(c, 1_000 + i, store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))


def test_a_topic_whose_names_change_is_deserialised(tmp_path, monkeypatch):
    _joint_state_bag(tmp_path / "bag", [["a", "b"]] * 5 + [["a", "b", "c"]] * 5)
    fast, fast_types, slow = _both(tmp_path / "bag", monkeypatch)
    assert fast_types == []
    _assert_same(fast, slow, {"/joint_states"})
    js = fast["/joint_states"]
    assert js["names"] == ["a", "b", "c"] and np.isnan(js["pos"][:5, 2]).all() and js["pos"][9, 2] == 2 + 0.5 * 9


def test_empty_effort_reads_as_nan_either_way(tmp_path, monkeypatch):
    _joint_state_bag(tmp_path / "bag", [["a", "b"]] * 6, effort=False)
    fast, fast_types, slow = _both(tmp_path / "bag", monkeypatch)
    assert fast_types == ["sensor_msgs/msg/JointState"]
    _assert_same(fast, slow, {"/joint_states"})
    assert np.isnan(fast["/joint_states"]["eff"]).all() and fast["/joint_states"]["pos"].shape == (6, 2)


def test_a_layout_that_reads_wrong_is_caught_by_the_sample(tmp_path, monkeypatch):
    """An Odometry layout off by one double (the pose read from the covariance's place): the sample
    that rosbags deserialises disagrees, the topic is deserialised, and the values are right."""
    write_flip_bag(tmp_path / "bag", dt=0.001, t_stand=0.2, t_rest=0.2, flight_time=0.3)

    def shifted(buf, names=None):
        names, layout = B.odometry_layout(buf, names)
        off, n, dt = layout["pose"]
        return names, {**layout, "pose": (off + 8, n, dt)}
    monkeypatch.setitem(B._LAYOUTS, "nav_msgs/msg/Odometry", shifted)
    fast, fast_types, slow = _both(tmp_path / "bag", monkeypatch)
    assert "nav_msgs/msg/Odometry" not in fast_types and "sensor_msgs/msg/JointState" in fast_types
    _assert_same(fast, slow, PER_STEP)


@pytest.mark.parametrize("n", [1, 3])
def test_short_topics(tmp_path, monkeypatch, n):
    _joint_state_bag(tmp_path / "bag", [["a"]] * n)
    fast, fast_types, slow = _both(tmp_path / "bag", monkeypatch)
    assert fast_types == ["sensor_msgs/msg/JointState"]
    _assert_same(fast, slow, {"/joint_states"})
