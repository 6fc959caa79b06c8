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
  geometry_msgs/msg/WrenchStamped  t_log, t, frame_id, force (N,3), torque (N,3)
  std_msgs/msg/String           t_log, data: list[str]

A bag without metadata.yaml (its recorder was killed: no MCAP summary or index either) is
recovered first (``recover_bag``): every complete chunk of its MCAP file is read as a streaming
reader reads it, and the bag is rewritten with its index and metadata.yaml.

Clock, Odometry, JointState and MotorCommand (the lockstep's tens of thousands of messages a run)
are read from their bytes at once when every message of the topic has the layout of the first
(flip_transport.cdr: the same size, strings and sequence lengths), and the result is checked
against rosbags' deserialisation of a sample of them (first, last and ~50 between); a topic that
differs anywhere is deserialised message by message, as every other type is.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from flip_transport.cdr import joint_state_layout, motor_command_layout, odometry_layout
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
    recovered: dict | None = None     # what recover_bag kept, when this bag had to be recovered
    derived: dict = field(default_factory=dict, repr=False, compare=False)   # computed once, read by several

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


#: topics the summary and plots do not read: left out by load_bag(..., exclude=NOT_SUMMARIZED) (the
#: robot's /tf at 200 Hz, 28 transforms a message, is most of a bag's deserialisation time)
NOT_SUMMARIZED = ("/tf", "/tf_static")


def load_bag(path: str | Path, topics: list[str] | None = None, exclude=()) -> BagData:
    """The bag's topics (``topics``: only those; ``exclude``: not those) as arrays (module doc)."""
    path = Path(path)
    recovered = None if (path / "metadata.yaml").exists() else recover_bag(path)
    data = BagData(path, recovered=recovered)      # (recovered: a killed recorder's bag, rewritten)
    raw: dict[str, tuple[str, list, list]] = {}        # topic -> (msgtype, log times ns, serialized)
    with Reader(path) as reader:
        data.start_ns, data.end_ns = reader.start_time, reader.end_time
        store = open_typestore_for(reader)
        data.constants = {c.msgtype: constants(c.msgtype, store) for c in reader.connections}
        for c in reader.connections:
            d = data.topics.setdefault(c.topic, {"type": c.msgtype, "count": 0})
            d["count"] += c.msgcount
        conns = [c for c in reader.connections
                 if (topics is None or c.topic in topics) and c.topic not in exclude]
        for c, t, msg in reader.messages(connections=conns):
            entry = raw.setdefault(c.topic, (c.msgtype, [], []))
            if entry[0] != c.msgtype:     # (ROS 2 matches one type a topic; here: keep the newest type)
                entry = raw[c.topic] = (c.msgtype, [], [])
            entry[1].append(t)
            entry[2].append(msg)
    for topic, (msgtype, ts, msgs) in raw.items():
        fast = _fast_arrays(msgtype, msgs, store)
        if fast is not None:
            fast["t_log"] = np.array([t * 1e-9 for t in ts])
            data.arrays[topic] = fast
            continue
        items = []
        for t, m in zip(ts, msgs):
            try:
                items.append((t * 1e-9, store.deserialize_cdr(m, msgtype)))
            except Exception:  # noqa: BLE001 - a message that does not deserialise is left out
                continue
        if items:
            data.arrays[topic] = _convert(msgtype, items)
    for topic in data.topics:
        if (topics is None or topic in topics) and topic not in exclude:
            data.arrays.setdefault(topic, {"t_log": np.zeros(0), "msgs": []})
    return data


#: per-step types read from their bytes at once: their flip_transport.cdr layout (None: a bare time)
_LAYOUTS = {"rosgraph_msgs/msg/Clock": None, "nav_msgs/msg/Odometry": odometry_layout,
            "sensor_msgs/msg/JointState": joint_state_layout, "flip_msgs/msg/MotorCommand": motor_command_layout}
_SAMPLES = 50


def _fast_arrays(msgtype: str, msgs: list, store) -> dict | None:
    """The arrays ``_convert`` would give for a topic of a per-step type, read from all its serialized
    messages at once, or None: another type, messages whose layout differs from the first one's
    (size, strings, sequence lengths), or a sample deserialised by rosbags that does not convert to
    the same values, to the bit."""
    if msgtype not in _LAYOUTS or not msgs:
        return None
    n, size = len(msgs), len(msgs[0])
    if any(len(m) != size for m in msgs):
        return None
    buf = b"".join(msgs)
    rows = np.frombuffer(buf, np.uint8).reshape(n, size)
    layout_fn = _LAYOUTS[msgtype]
    names, layout = (None, {}) if layout_fn is None else layout_fn(msgs[0])
    numeric = np.zeros(size, bool)
    numeric[4:12] = True                                  # the stamp (a header's, or the bare time)
    for off, k, dt in layout.values():
        numeric[off:off + k * dt.itemsize] = True
    if not (rows[:, ~numeric] == rows[0, ~numeric]).all():
        return None

    def column(off, k, dt):
        return np.ndarray((n, k), dt, buffer=buf, offset=off, strides=(size, dt.itemsize)).copy()
    sec, nanosec = column(4, 1, np.dtype("<i4"))[:, 0], column(8, 1, np.dtype("<u4"))[:, 0]
    t = sec.astype(float) + 1e-9 * nanosec.astype(float)
    f = {k: column(*v) for k, v in layout.items()}
    if msgtype == "rosgraph_msgs/msg/Clock":
        out = {"sim_t": t}
    elif msgtype == "nav_msgs/msg/Odometry":
        pose, twist = f["pose"], f["twist"]
        out = {"t": t, "pos": pose[:, :3].copy(), "quat": pose[:, 3:7].copy(), "lin": twist[:, :3].copy(),
               "ang": twist[:, 3:].copy()}
    else:
        names = names[0]
        if len(set(names)) != len(names):
            return None

        def matrix(a):                                    # (n, len(names)), NaN where a value is missing
            m = np.full((n, len(names)), np.nan)
            k = min(a.shape[1], len(names))
            m[:, :k] = a[:, :k]
            return m
        if msgtype == "sensor_msgs/msg/JointState":
            out = {"t": t, "names": list(names), "pos": matrix(f["position"]), "vel": matrix(f["velocity"]),
                   "eff": matrix(f["effort"])}
        else:
            out = {"t": t, "step": f["step"][:, 0].astype(np.int64), "names": list(names),
                   "effort": matrix(f["effort"]), "compute_time_us": f["compute_time_us"][:, 0].astype(float)}
    # rosbags' reading of a sample (first, last, ~50 between) must give the same values
    idx = np.unique(np.r_[0, n - 1, np.linspace(0, n - 1, _SAMPLES).astype(int)])
    try:
        ref = _CONVERTERS[msgtype]([store.deserialize_cdr(msgs[i], msgtype) for i in idx])
    except Exception:  # noqa: BLE001 - let the message-by-message path deal with it
        return None
    for key, val in ref.items():
        if isinstance(val, np.ndarray):
            if not np.array_equal(out[key][idx], val, equal_nan=True):
                return None
        elif key in out and out[key] != val:
            return None
        else:
            out[key] = val                                # frame ids: the same in every message
    return out


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


def _wrench_stamped(msgs):
    return {"t": np.array([_stamp(m.header.stamp) for m in msgs]),
            "frame_id": msgs[0].header.frame_id if msgs else "",
            "force": np.array([_vec(m.wrench.force) for m in msgs]).reshape(-1, 3),
            "torque": np.array([_vec(m.wrench.torque) for m in msgs]).reshape(-1, 3)}


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
    "geometry_msgs/msg/WrenchStamped": _wrench_stamped,
}


# ------------------------------------------------------------------------------- recovery
def scan_mcap(path: str | Path) -> dict:
    """Schemas, channels and messages of an MCAP file read front to back by mcap's streaming reader
    (no summary or index needed; chunks decompressed); a truncated or undecodable tail is left out.
    Returns {"schemas": {id: (name, encoding, data)}, "channels": {id: (topic, schema id, message
    encoding, metadata)}, "messages": [(channel id, log time, data)], "bytes_read": offset of the end
    of the last whole record, "size": file size}."""
    from mcap.records import Channel, DataEnd, Footer, Message, Schema
    from mcap.stream_reader import StreamReader
    path = Path(path)
    out = {"schemas": {}, "channels": {}, "messages": [], "bytes_read": 0, "size": path.stat().st_size}
    with open(path, "rb") as f:
        try:
            for rec in StreamReader(f).records:
                if isinstance(rec, Schema):
                    out["schemas"][rec.id] = (rec.name, rec.encoding, rec.data.decode())
                elif isinstance(rec, Channel):
                    out["channels"][rec.id] = (rec.topic, rec.schema_id, rec.message_encoding, rec.metadata)
                elif isinstance(rec, Message):
                    out["messages"].append((rec.channel_id, rec.log_time, rec.data))
                elif isinstance(rec, (DataEnd, Footer)):
                    out["bytes_read"] = out["size"]          # the data section is whole: nothing cut off
                    break
                out["bytes_read"] = f.tell()
        except Exception:  # noqa: BLE001 - the cut-off tail of a file whose writer was killed
            pass
    return out


def recover_bag(path: str | Path) -> dict | None:
    """Rewrite a bag that has no metadata.yaml (its recorder died) from what its MCAP file holds
    (``scan_mcap``: every whole chunk), with a summary, index and metadata.yaml, zstd-compressed as
    the recorder writes; the unindexed file is replaced. Returns what was kept: {"messages",
    "topics": {topic: count}, "bytes_kept", "bytes_dropped", "log_time_s": [first, last]}, or None
    when there is nothing to recover (a bag with metadata.yaml, or no MCAP file)."""
    import shutil

    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
    from rosbags.rosbag2.storage_mcap import parse_qos
    from rosbags.typesys import Stores, get_typestore
    path = Path(path)
    if (path / "metadata.yaml").exists():
        return None
    files = sorted(path.glob("*.mcap"))
    if not files:
        return None
    scans = [scan_mcap(f) for f in files]
    # written beside the bag under the bag's own name, then moved into it, metadata.yaml last
    tmp_root = path.with_name(path.name + ".recovering")
    shutil.rmtree(tmp_root, ignore_errors=True)
    tmp_root.mkdir()
    tmp = tmp_root / path.name
    writer = Writer(tmp, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    writer.open()
    store = get_typestore(Stores.ROS2_JAZZY)
    fallback = flip_typestore()
    topics: dict[str, int] = {}
    times = []
    added = {}
    try:
        for scan in scans:
            conns = {}
            for cid, (topic, sid, enc, meta) in scan["channels"].items():
                name, _fmt, text = scan["schemas"].get(sid, ("", "", ""))
                key = (topic, name, enc, tuple(sorted(meta.items())))
                if key in added:
                    conns[cid] = added[key]
                    continue
                qos = meta.get("offered_qos_profiles")
                try:
                    if name not in store.fielddefs:
                        store.register(get_types_from_msg(text, name))
                    rihs01 = store.hash_rihs01(name)
                except Exception:  # noqa: BLE001 - a definition rosbags cannot parse: the source tree's
                    rihs01 = fallback.hash_rihs01(name) if name in fallback.fielddefs else "RIHS01_" + "0" * 64
                conns[cid] = writer.add_connection(topic, name, msgdef=text, rihs01=rihs01,
                                                   serialization_format=enc or "cdr",
                                                   offered_qos_profiles=parse_qos(qos) if qos else [])
                added[key] = conns[cid]
            for cid, t, msg in scan["messages"]:
                if cid in conns:
                    writer.write(conns[cid], t, msg)
                    topics[conns[cid].topic] = topics.get(conns[cid].topic, 0) + 1
                    times.append(t)
        writer.close()
    except BaseException:
        writer.abort()
        shutil.rmtree(tmp_root, ignore_errors=True)
        raise
    # the rewritten file replaces the unindexed one of its name (the others go), metadata.yaml last
    new = sorted(tmp.glob("*.mcap"))
    for f in new:
        f.replace(path / f.name)
    for f in files:
        if f.name not in {g.name for g in new}:
            f.unlink()
    (tmp / "metadata.yaml").replace(path / "metadata.yaml")
    shutil.rmtree(tmp_root, ignore_errors=True)
    kept = sum(s["bytes_read"] for s in scans)
    return {"messages": sum(topics.values()), "topics": topics, "bytes_kept": kept,
            "bytes_dropped": sum(s["size"] for s in scans) - kept,
            "log_time_s": [min(times) * 1e-9, max(times) * 1e-9] if times else None}
