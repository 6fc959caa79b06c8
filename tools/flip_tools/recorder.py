"""A stand-in for `ros2 bag record`: rclpy raw subscriptions -> rosbags' rosbag2 MCAP Writer.

- Serialized CDR bytes go straight from the subscription (raw=True) to the bag; no
  deserialisation, and no executor: every POLL_S the main loop takes whatever each subscription
  has queued (a 2 kHz lockstep sends ~8,000 messages a second; one executor callback each cost
  ~250 µs of CPU, which the simulator and the controller need on a 2-core machine).
- Log time = the RMW's receive timestamp (wall clock, ns) of each message, stamped by the DDS
  reader when the message arrived (not when the main loop takes it), so the bag shows the rate
  the graph ran at; a recorder whose DDS thread was stalled stamps the backlog when it resumes
  (flip_tools.launcher's Fast DDS profile keeps that backlog instead of dropping it).
- Subscription QoS follows the publishers (like rosbag2's adaptive QoS): reliable only if every
  publisher is reliable, transient-local only if every publisher is; before any publisher is seen,
  the contract table of docs/architecture.md decides. Depth is large (10,000) so bursts queue.
- Topics are either given, or discovered (`all_topics=True`: every topic that appears, polled
  from the graph, except /parameter_events).
- flip_msgs types come from the .msg files (rosbags.typesys.get_types_from_msg), so the bag
  carries their full message definitions.
- Progress on /flip_recorder/status (std_msgs/String, JSON): messages recorded and publishers
  matched per topic and the stamp of the newest /clock recorded (``last_clock_ns``), twice a
  second; an orchestrator waits on "matched" before it starts the experiment (another process
  seeing both endpoints does not mean they have matched), and on "last_clock_ns" before it stops
  the recorder.
- The MCAP chunks are zstd-compressed (``FLIP_BAG_COMPRESSION=none``: uncompressed), as `ros2 bag
  record -s mcap` writes them, and each goes to the file whole when it is closed (at 1 MiB, or
  CHUNK_MAX_S after its first message): a recorder killed mid-run leaves every closed chunk
  readable front to back, and flip_tools.bag.recover_bag rebuilds the index and metadata.yaml.
- SIGINT/SIGTERM, or `duration`, ends the recording; the bag is closed, counts are printed as one
  JSON line `{"recorded": {...}}` on stdout.
"""
from __future__ import annotations

import json
import os
import signal
import struct
import time
from pathlib import Path

from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

from .rosenv import CONTRACT_TOPICS, message_class
from .typestore import flip_typestore

RECORDER_NODE = "flip_recorder"
SUB_DEPTH = 10000
EXCLUDE = {"/parameter_events"}
POLL_S = 0.01          # main loop period: take what is queued, write it
DISCOVER_S = 0.2       # period of the graph poll for new topics
STATUS_S = 0.5         # period of /<node>/status
CHUNK_MAX_S = 1.0      # a chunk with messages goes to the file this long after it was begun, at the latest
_CLOCK_STAMP = struct.Struct("<iI")   # rosgraph_msgs/Clock's time, after the 4-byte CDR header


def _rb_qos(reliable: bool, transient_local: bool, depth: int) -> Qos:
    """The offered QoS written to metadata.yaml (rosbag2 v9 form)."""
    z = QosTime(0, 0)
    return Qos(QosHistory.KEEP_LAST, depth,
               QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
               QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE,
               z, z, QosLiveliness.AUTOMATIC, z, False)


def _ignore(_msg):
    return None


class Recorder:
    """Subscriptions of one node (never spun by an executor) written to a bag by ``take_all``."""

    def __init__(self, node, bag_dir: str | Path, topics: list[str] | None = None,
                 all_topics: bool = False, types: dict[str, str] | None = None, compression: str = "zstd"):
        self.node = node
        self.bag_dir = Path(bag_dir)
        self.want = list(topics or [])
        self.all_topics = all_topics or not self.want
        self.types = dict(types or {})
        self.typestore = flip_typestore()
        self.writer = Writer(self.bag_dir, version=9, storage_plugin=StoragePlugin.MCAP)
        self.compression = compression
        if compression == "zstd":
            self.writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        elif compression != "none":
            raise ValueError(f"bag compression must be 'zstd' or 'none', not {compression!r}")
        self.writer.open()
        self._flush_closed_chunks()
        self._chunk_begun = None
        self.conns: dict[str, object] = {}
        self.subs: dict[str, object] = {}
        self.counts: dict[str, int] = {}
        self.qos_used: dict[str, dict] = {}
        self.last_clock_ns: int | None = None
        self.closed = False
        # progress for whoever orchestrates: {"counts": {...}} on /<node>/status, twice a second
        from std_msgs.msg import String
        self._String = String
        self.status_topic = node.get_fully_qualified_name() + "/status"
        self._status_pub = node.create_publisher(String, self.status_topic, 10)
        self.discover()

    def _flush_closed_chunks(self) -> None:
        """Every chunk rosbags' MCAP writer closes goes to the file at once (not left in the file
        object's buffer), so that what a killed recorder leaves ends with whole chunks."""
        storage = self.writer.storage
        close_chunk = storage.close_chunk

        def close_and_flush():
            close_chunk()
            storage.bio.flush()
        storage.close_chunk = close_and_flush
        storage.bio.flush()                   # the MCAP magic and header

    def close_old_chunk(self, now: float) -> None:
        """Close the pending chunk once CHUNK_MAX_S have passed since its first message (at a low
        rate a 1 MiB chunk would hold minutes that a killed recorder loses)."""
        storage = self.writer.storage
        if storage is None or not storage.chunk.msgs:
            self._chunk_begun = None
        elif self._chunk_begun is None:
            self._chunk_begun = now
        elif now - self._chunk_begun >= CHUNK_MAX_S:
            storage.close_chunk()
            self._chunk_begun = None

    def publish_status(self) -> None:
        if not self.closed:
            self._status_pub.publish(self._String(data=json.dumps({"counts": self.counts,
                                                                   "matched": self.matched(),
                                                                   "last_clock_ns": self.last_clock_ns})))

    def matched(self) -> dict[str, int]:
        """Publishers each subscription is matched with, as this process's DDS sees it (the graph
        seen by another process can be ahead: discovery is per participant)."""
        out = {}
        for topic, sub in self.subs.items():
            if sub is not None:
                try:
                    out[topic] = sub.get_publisher_count()
                except Exception:  # noqa: BLE001
                    out[topic] = 0
        return out

    # -- subscription management ----------------------------------------------------------------
    def _graph_type(self, topic: str) -> str | None:
        for name, types in self.node.get_topic_names_and_types():
            if name == topic and types:
                return types[0]
        return None

    def _adaptive_qos(self, topic: str):
        """(reliable, transient_local) matching every publisher seen; None if no publisher."""
        infos = self.node.get_publishers_info_by_topic(topic)
        if not infos:
            return None
        from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
        rel = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
        tl = all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
        return rel, tl

    def discover(self) -> None:
        if self.closed:
            return
        wanted = list(self.want)
        if self.all_topics:
            for name, _types in self.node.get_topic_names_and_types():
                if name not in EXCLUDE and name != self.status_topic and name not in wanted:
                    wanted.append(name)
        for topic in wanted:
            if topic not in self.subs:
                self._try_subscribe(topic)

    def _try_subscribe(self, topic: str) -> None:
        msgtype = self.types.get(topic) or self._graph_type(topic)
        spec = CONTRACT_TOPICS.get(topic)
        if msgtype is None and spec is not None:
            msgtype = spec.msgtype
        if msgtype is None:
            return  # not typed yet; retry on the next discovery tick
        q = self._adaptive_qos(topic)
        if q is None:
            if spec is None:
                return  # wait for a publisher to learn its QoS
            q = (spec.reliable, spec.transient_local)
        rel, tl = q
        try:
            cls = message_class(msgtype)
        except (ImportError, AttributeError) as e:
            self.node.get_logger().warning(f"cannot record {topic} [{msgtype}]: {e}")
            self.subs[topic] = None
            return
        try:
            self.typestore.fielddefs[msgtype]
        except KeyError:
            self.node.get_logger().warning(f"cannot record {topic}: {msgtype} not in the rosbags typestore")
            self.subs[topic] = None
            return
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=SUB_DEPTH,
                         reliability=ReliabilityPolicy.RELIABLE if rel else ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL if tl else DurabilityPolicy.VOLATILE)
        conn = self.writer.add_connection(topic, msgtype, typestore=self.typestore,
                                          offered_qos_profiles=[_rb_qos(rel, tl, spec.depth if spec else 10)])
        self.conns[topic] = conn
        self.counts[topic] = 0
        self.qos_used[topic] = {"type": msgtype, "reliable": rel, "transient_local": tl}
        self.subs[topic] = self.node.create_subscription(cls, topic, _ignore, qos, raw=True)

    # -- hot path ---------------------------------------------------------------------------------
    def take_all(self) -> None:
        """Write every message queued on every subscription, stamped with its receive time."""
        write = self.writer.write
        for topic, sub in self.subs.items():
            if sub is None:
                continue
            conn, n, raw = self.conns[topic], 0, None
            while (r := sub.handle.take_message(sub.msg_type, True)) is not None:
                t = r[1].get("received_timestamp") or time.time_ns()
                raw = r[0]
                write(conn, t, raw)
                n += 1
            self.counts[topic] += n
            if topic == "/clock" and raw is not None and len(raw) >= 12:
                sec, nanosec = _CLOCK_STAMP.unpack_from(raw, 4)
                self.last_clock_ns = max(self.last_clock_ns or 0, sec * 1_000_000_000 + nanosec)

    def close(self) -> dict:
        if not self.closed:
            self.closed = True
            self.writer.close()
        return dict(self.counts)


def record(bag_dir: str | Path, topics: list[str] | None = None, all_topics: bool = False,
           duration: float | None = None, domain_id: int | None = None, node_name: str = RECORDER_NODE,
           stats_path: str | Path | None = None) -> dict:
    """Run a recorder in this process until SIGINT/SIGTERM or `duration` wall seconds."""
    import rclpy

    bag_dir = Path(bag_dir)
    if bag_dir.exists():
        raise FileExistsError(f"{bag_dir} exists; rosbag2 needs a new directory")
    bag_dir.parent.mkdir(parents=True, exist_ok=True)
    stop = {"flag": False}

    def _on_signal(signum, frame):
        stop["flag"] = True

    rclpy.init(domain_id=domain_id, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    signal.signal(signal.SIGINT, _on_signal)
    signal.signal(signal.SIGTERM, _on_signal)
    node = rclpy.create_node(node_name, start_parameter_services=False)
    rec = Recorder(node, bag_dir, topics, all_topics, compression=os.environ.get("FLIP_BAG_COMPRESSION", "zstd"))
    t0 = time.monotonic()
    next_discover = next_status = t0
    try:
        while not stop["flag"] and (duration is None or time.monotonic() - t0 < duration):
            rec.take_all()
            now = time.monotonic()
            rec.close_old_chunk(now)
            if now >= next_discover:
                rec.discover()
                next_discover = now + DISCOVER_S
            if now >= next_status:
                rec.publish_status()
                next_status = now + STATUS_S
            time.sleep(POLL_S)
        rec.take_all()
    finally:
        counts = rec.close()
        try:
            node.destroy_node()
        except Exception:
            pass
        rclpy.try_shutdown()
    stats = {"recorded": counts, "bag": str(bag_dir), "qos": rec.qos_used,
             "wall_s": round(time.monotonic() - t0, 3)}
    if stats_path:
        Path(stats_path).write_text(json.dumps(stats, indent=2))
    print(json.dumps(stats), flush=True)
    return stats
