"""Read a rosbag2 (MCAP or sqlite3) back into numpy arrays per topic, with rosbags. No ROS import.

    data = load_bag("runs/demo/bag")
    data.topics            {"/odom": {"type": "nav_msgs/msg/Odometry", "count": 5123}, ...}
    data["/odom"]          dict of arrays: t_log (s, wall receive time), t (s, header stamp = sim
                           time), pos (N,3), quat (N,4, x y z w), lin (N,3), ang (N,3) (child frame)
    data.get("/nope")      None for a topic that is not in the bag
    data.constants         {msgtype: {CONSTANT: value}} from the definitions in the bag

Per type (others: {"t_log", "msgs"} with the deserialised messages):
  rosgraph_msgs/msg/Clock       t_log, sim_t
  nav_msgs/msg/Odometry         t_log, t, pos, quat, lin, ang
  sensor_msgs/msg/JointState    t_log, t, names, pos, vel, eff   (N, J); NaN where a name is absent
  flip_msgs/msg/MotorCommand    t_log, t, step, names, effort (N, M), compute_time_us
  flip_msgs/msg/ContactEvent    t_log, t, frame_id, step, event, domain, pelvis_pos, pelvis_quat, com_pos,
                                com_vel, H_pitch, left_normal_force, right_normal_force, support_center
  flip_msgs/msg/FlipReference   t_log, refs: list of dicts (plan_id, domain, start_time, t,
                                output_names, value (n,k), d_value, dd_value, parameters{}, figures)
  std_msgs/msg/String           t_log, data: list[str]
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.typesys import get_types_from_msg

from .typestore import flip_typestore


def _stamp(s) -> float:
    return s.sec + 1e-9 * s.nanosec


def _vec(v) -> list[float]:
    return [v.x, v.y, v.z]


def _quat(q) -> list[float]:
    return [q.x, q.y, q.z, q.w]


@dataclass
class BagData:
    path: Path
    topics: dict[str, dict] = field(default_factory=dict)
    arrays: dict[str, dict] = field(default_factory=dict)
    constants: dict[str, dict] = field(default_factory=dict)   # msgtype -> {NAME: value}
    start_ns: int | None = None
    end_ns: int | None = None

    def __getitem__(self, topic: str) -> dict:
        return self.arrays[topic]

    def __contains__(self, topic: str) -> bool:
        return topic in self.arrays and self.topics.get(topic, {}).get("count", 0) > 0

    def get(self, topic: str, default=None):
        return self.arrays.get(topic, default) if topic in self else default

    def count(self, topic: str) -> int:
        return self.topics.get(topic, {}).get("count", 0)


def open_typestore_for(reader: Reader):
    """A typestore for this bag: ROS 2 Jazzy's standard types, plus every other type from the
    definition the bag itself carries (so an old bag reads with the definition it was written
    with), plus flip_msgs from the source tree for a connection without a definition."""
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS2_JAZZY)
    std = set(store.fielddefs)
    extra: dict = {}
    missing = []
    for c in reader.connections:
        if c.msgtype in std or c.msgtype in extra:
            continue
        md = getattr(c, "msgdef", None)
        text = getattr(md, "data", md)
        try:
            if not text:
                raise ValueError("no definition in the bag")
            extra.update({k: v for k, v in get_types_from_msg(text, c.msgtype).items() if k not in std})
        except Exception:  # noqa: BLE001 - fall back to the source tree's definition
            missing.append(c.msgtype)
    if missing:
        fts = flip_typestore()
        extra.update({k: v for k, v in fts.fielddefs.items() if k not in std and k not in extra})
    if extra:
        store.register(extra)
    return store


def constants(msgtype: str, store=None) -> dict[str, int]:
    """Constants of a message type, e.g. constants('flip_msgs/msg/ContactEvent')['BODY_CONTACT']."""
    store = store or flip_typestore()
    try:
        return {n: v for n, _t, v in store.fielddefs[msgtype][0]}
    except KeyError:
        return {}


def iter_messages(path: str | Path, topics: list[str] | None = None):
    """Yield (topic, msgtype, log_time_ns, message) in log-time order."""
    with Reader(Path(path)) as reader:
        store = open_typestore_for(reader)
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        for c, t, raw in reader.messages(connections=conns):
            try:
                msg = store.deserialize_cdr(raw, c.msgtype)
            except Exception:  # noqa: BLE001
                continue
            yield c.topic, c.msgtype, t, msg


def load_bag(path: str | Path, topics: list[str] | None = None) -> BagData:
    path = Path(path)
    data = BagData(path)
    with Reader(path) as reader:
        data.start_ns, data.end_ns = reader.start_time, reader.end_time
        store = open_typestore_for(reader)
        data.constants = {c.msgtype: constants(c.msgtype, store) for c in reader.connections}
        for c in reader.connections:
            d = data.topics.setdefault(c.topic, {"type": c.msgtype, "count": 0})
            d["count"] += c.msgcount
    raw: dict[str, list] = {}
    types: dict[str, str] = {}
    for topic, msgtype, t, msg in iter_messages(path, topics):
        raw.setdefault(topic, []).append((t * 1e-9, msg))
        types[topic] = msgtype
    for topic, items in raw.items():
        data.arrays[topic] = _convert(types[topic], items)
    for topic in data.topics:
        if topics is None or topic in topics:
            data.arrays.setdefault(topic, {"t_log": np.zeros(0), "msgs": []})
    return data


def _convert(msgtype: str, items: list) -> dict:
    t_log = np.array([t for t, _ in items])
    msgs = [m for _, m in items]
    fn = _CONVERTERS.get(msgtype)
    out = fn(msgs) if fn else {"msgs": msgs}
    out["t_log"] = t_log
    return out


def _clock(msgs):
    return {"sim_t": np.array([_stamp(m.clock) for m in msgs])}


def _odom(msgs):
    return {"t": np.array([_stamp(m.header.stamp) for m in msgs]),
            "pos": np.array([_vec(m.pose.pose.position) for m in msgs]).reshape(-1, 3),
            "quat": np.array([_quat(m.pose.pose.orientation) for m in msgs]).reshape(-1, 4),
            "lin": np.array([_vec(m.twist.twist.linear) for m in msgs]).reshape(-1, 3),
            "ang": np.array([_vec(m.twist.twist.angular) for m in msgs]).reshape(-1, 3),
            "frame_id": msgs[0].header.frame_id if msgs else "",
            "child_frame_id": msgs[0].child_frame_id if msgs else ""}


def _named_matrix(msgs, names_of, fields):
    names: list[str] = []
    index: dict[str, int] = {}
    for m in msgs:
        for n in names_of(m):
            if n not in index:
                index[n] = len(names)
                names.append(n)
    out = {}
    for f in fields:
        a = np.full((len(msgs), len(names)), np.nan)
        for i, m in enumerate(msgs):
            vals = np.asarray(getattr(m, f), dtype=float)
            ns = names_of(m)
            k = min(len(vals), len(ns))
            if k:
                a[i, [index[n] for n in ns[:k]]] = vals[:k]
        out[f] = a
    out["names"] = names
    return out


def _joint_states(msgs):
    out = _named_matrix(msgs, lambda m: list(m.name), ["position", "velocity", "effort"])
    return {"t": np.array([_stamp(m.header.stamp) for m in msgs]), "names": out["names"],
            "pos": out["position"], "vel": out["velocity"], "eff": out["effort"]}


def _motor_command(msgs):
    out = _named_matrix(msgs, lambda m: list(m.name), ["effort"])
    return {"t": np.array([_stamp(m.header.stamp) for m in msgs]),
            "step": np.array([m.step for m in msgs], dtype=np.int64),
            "names": out["names"], "effort": out["effort"],
            "compute_time_us": np.array([m.compute_time_us for m in msgs], dtype=float)}


def _contact_event(msgs):
    return {"t": np.array([_stamp(m.header.stamp) for m in msgs]),
            "frame_id": [m.header.frame_id for m in msgs],   # BODY_CONTACT: the bodies touching
            "step": np.array([m.step for m in msgs], dtype=np.int64),
            "event": np.array([m.event for m in msgs], dtype=int),
            "domain": np.array([m.domain for m in msgs], dtype=int),
            "pelvis_pos": np.array([_vec(m.pelvis_pose.position) for m in msgs]).reshape(-1, 3),
            "pelvis_quat": np.array([_quat(m.pelvis_pose.orientation) for m in msgs]).reshape(-1, 4),
            "com_pos": np.array([_vec(m.com_position) for m in msgs]).reshape(-1, 3),
            "com_vel": np.array([_vec(m.com_velocity) for m in msgs]).reshape(-1, 3),
            "H_pitch": np.array([m.centroidal_pitch_momentum for m in msgs]),
            "left_normal_force": np.array([m.left_normal_force for m in msgs]),
            "right_normal_force": np.array([m.right_normal_force for m in msgs]),
            # NaN for a bag whose ContactEvent definition predates the field
            "support_center": np.array([_vec(m.support_center) if hasattr(m, "support_center") else [np.nan] * 3
                                        for m in msgs]).reshape(-1, 3)}


def _flip_reference(msgs):
    refs = []
    for m in msgs:
        t = np.asarray(m.t, dtype=float)
        k = len(m.output_names)

        def shape(v):
            v = np.asarray(v, dtype=float)
            return v.reshape(len(t), k) if k and v.size == len(t) * k else v
        refs.append({"plan_id": int(m.plan_id), "domain": int(m.domain), "stamp": _stamp(m.header.stamp),
                     "start_time": _stamp(m.start_time), "t": t, "output_names": list(m.output_names),
                     "value": shape(m.value), "d_value": shape(m.d_value), "dd_value": shape(m.dd_value),
                     "parameters": dict(zip(m.parameter_names, map(float, m.parameter_values))),
                     "liftoff_zdot": m.liftoff_zdot, "liftoff_xdot": m.liftoff_xdot,
                     "flight_time": m.flight_time, "rotation_to_go": m.rotation_to_go,
                     "peak_flywheel_speed": m.peak_flywheel_speed, "solve_time": m.solve_time,
                     "iterations": int(m.iterations)})
    return {"refs": refs}


def _string(msgs):
    return {"data": [m.data for m in msgs]}


_CONVERTERS = {
    "rosgraph_msgs/msg/Clock": _clock,
    "nav_msgs/msg/Odometry": _odom,
    "sensor_msgs/msg/JointState": _joint_states,
    "flip_msgs/msg/MotorCommand": _motor_command,
    "flip_msgs/msg/ContactEvent": _contact_event,
    "flip_msgs/msg/FlipReference": _flip_reference,
    "std_msgs/msg/String": _string,
}
