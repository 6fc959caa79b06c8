"""The live view's ROS side: rclpy raw subscriptions -> flip_tools.live.LiveServer (Foxglove WebSocket).

Started by `flip run|stand|sim --live` as its own process (node ``flip_live``), like the recorder:

    python -m flip_tools.live_node --port 8765 [--domain N]     (on a running graph)

- Channels: the contract topics of docs/architecture.md at once, and every other topic that appears
  in the graph (polled, as the recorder's ``--all`` does), typed by the rosbags typestore.
- Reading: latched (transient-local) topics always, reliable and transient local; /clock (the sim
  time) and the others best effort, not before SIGUSR1 says the graph runs with ``--hold-streams``
  (flip: a client's reader must not count as one of those sim_node waits for), and the others only
  while a Foxglove client is subscribed to their channel, so that nobody watching adds no reader
  to the lockstep's per-step topics.
- Off the lockstep's CPU (flip_transport.lockstep.avoid_lockstep_cpu), niced by flip.
- No executor: every POLL_S (IDLE_POLL_S while no client is subscribed to anything: a live view
  nobody watches wakes up 20 times a second) the loop takes what each subscription has queued, serialized
  (raw=True), and forwards the bytes: the per-step streams on the sim-time grid (``--rate``, default
  200 Hz of sim time; picked by flip_transport._rcl_io.take_on_grid), log time = sim time
  (flip_tools.live).
- Prints ``live: serving ws://127.0.0.1:PORT`` once it listens (flip reads the port from its log);
  a port it cannot bind ends it with exit 3 and the reason. SIGINT/SIGTERM stop it.
"""
from __future__ import annotations

import argparse
import json
import signal
import sys
import time

from .live import (DEFAULT_PORT, LIVE_HOST, SERVING_PREFIX, STEP_STREAMS, STREAM_RATE_HZ, LiveServer, LiveTopics,
                   NewSteps, header_stamp_ns, port_arg)
from .rosenv import CONTRACT_TOPICS, message_class

NODE_NAME = "flip_live"
POLL_S = 0.01          # take what is queued, forward it
IDLE_POLL_S = 0.05     # the same while nobody is subscribed (latched topics kept, /clock followed)
DISCOVER_S = 0.5       # graph poll: new topics, and subscriptions to follow the clients'
LATCHED_DEPTH = 10     # kept of a latched topic outside the contract table
READ_DEPTH = 1000      # reader queue of a streamed topic (best effort: older messages dropped)


def _ignore(_msg):
    return None


class LiveBridge:
    """One rclpy node (never spun) reading the graph's topics into a LiveServer."""

    def __init__(self, node, server: LiveServer, streams: bool = True, rate_hz: float = STREAM_RATE_HZ):
        self.node = node
        self.server = server
        self.streams = streams          # may the streamed topics be read yet
        self.grid_ns = int(round(1e9 / rate_hz)) if rate_hz > 0 else 0   # 0: every message
        self.sim_ns = 0                 # newest sim time seen: the log time of what has no stamp of its own
        self.topics = LiveTopics()
        self.new_steps = NewSteps()     # a re-sent state (same stamp) forwarded once
        self.subs: dict[str, object] = {}
        self.unreadable: set[str] = set()
        for spec in CONTRACT_TOPICS.values():
            self._offer(spec.name, spec.msgtype, spec.transient_local, spec.depth, spec.reliable)
        self.update()

    def _offer(self, topic, msgtype, transient_local, depth, reliable) -> None:
        if topic in self.unreadable:
            return
        try:
            message_class(msgtype)
            problem = None if msgtype in self.server.typestore.fielddefs else "not in the rosbags typestore"
        except (ImportError, AttributeError, ValueError) as e:
            problem = repr(e)
        if problem:
            self.node.get_logger().warning(f"no channel for {topic} [{msgtype}]: {problem}")
            self.unreadable.add(topic)
            return
        info = self.topics.offer(topic, msgtype, transient_local, depth, reliable)
        if info is not None:
            self.server.add_channel(info)

    def discover(self) -> None:
        """Channels for the topics that appeared (QoS of their publishers, as the recorder's)."""
        from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
        for name, types in self.node.get_topic_names_and_types():
            if name in self.topics.topics or not types:
                continue
            infos = self.node.get_publishers_info_by_topic(name)
            if not infos:
                continue
            tl = all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
            rel = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
            self._offer(name, types[0], tl, LATCHED_DEPTH, rel)

    def update(self) -> None:
        """Subscriptions to match what is wanted: latched topics, and the streamed topics some
        client is subscribed to."""
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
        want = self.topics.wanted(self.server.subscribed(), self.streams)
        for topic in [t for t in self.subs if t not in want]:
            self.node.destroy_subscription(self.subs.pop(topic))
        for topic in want - set(self.subs):
            info = self.topics.topics[topic]
            if info.latched:
                qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=info.latched,
                                 reliability=ReliabilityPolicy.RELIABLE if info.reliable else ReliabilityPolicy.BEST_EFFORT,
                                 durability=DurabilityPolicy.TRANSIENT_LOCAL)
            else:
                qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=READ_DEPTH,
                                 reliability=ReliabilityPolicy.BEST_EFFORT, durability=DurabilityPolicy.VOLATILE)
            self.subs[topic] = self.node.create_subscription(message_class(info.msgtype), topic, _ignore, qos,
                                                             raw=True)

    def _take_stamped(self, sub) -> list:
        """(stamp ns, bytes) of a per-step stream's queued messages on the grid (all: grid_ns 0)."""
        if self.grid_ns:
            from flip_transport import _rcl_io
            return _rcl_io.take_on_grid(sub.handle.pointer, self.grid_ns)
        out = []
        while (r := sub.handle.take_message(sub.msg_type, True)) is not None:
            out.append((header_stamp_ns(r[0]) or self.sim_ns, r[0]))
        return out

    def take_all(self) -> int:
        """Forward what is queued: the per-step streams first (their stamps advance the sim time),
        then the rest, stamped with the newest sim time; how many were forwarded."""
        n = 0
        forward = self.server.forward
        for topic in STEP_STREAMS:
            sub = self.subs.get(topic)
            for ns, raw in (self._take_stamped(sub) if sub is not None else ()):
                if not self.new_steps.fresh(topic, ns):
                    continue
                self.sim_ns = max(self.sim_ns, ns)
                forward(topic, raw, ns)
                n += 1
        for topic, sub in self.subs.items():
            if topic in STEP_STREAMS:
                continue
            while (r := sub.handle.take_message(sub.msg_type, True)) is not None:
                forward(topic, r[0], self.sim_ns)
                n += 1
        return n


def serve(port: int, domain_id: int | None = None, host: str = LIVE_HOST, duration: float | None = None,
          hold_streams: bool = False, rate_hz: float = STREAM_RATE_HZ) -> int:
    """Listen on host:port, then forward the graph's topics until SIGINT/SIGTERM (or ``duration``);
    ``hold_streams``: the streamed topics only after SIGUSR1."""
    from flip_transport.lockstep import avoid_lockstep_cpu
    from .typestore import flip_typestore
    # off the lockstep's CPU, like the state publisher (before the server's and DDS's threads start)
    avoid_lockstep_cpu()
    stop = {"flag": False, "streams": not hold_streams}

    def _on_signal(signum, frame):
        stop["flag"] = True

    def _on_release(signum, frame):
        stop["streams"] = True
    signal.signal(signal.SIGINT, _on_signal)
    signal.signal(signal.SIGTERM, _on_signal)
    signal.signal(signal.SIGUSR1, _on_release)      # before the serving line: flip may send it from then on
    try:
        server = LiveServer(port, host, typestore=flip_typestore())
    except OSError as e:
        print(f"live: {e}", flush=True)
        return 3
    print(f"{SERVING_PREFIX}{host}:{server.port}", flush=True)
    import rclpy
    rclpy.init(domain_id=domain_id, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    node = rclpy.create_node(NODE_NAME, start_parameter_services=False)
    t0 = time.monotonic()
    try:
        bridge = LiveBridge(node, server, streams=stop["streams"], rate_hz=rate_hz)
        next_discover = t0
        while not stop["flag"] and (duration is None or time.monotonic() - t0 < duration):
            server.replay_latched(bridge.sim_ns)
            bridge.take_all()
            now = time.monotonic()
            if now >= next_discover:
                bridge.discover()
                next_discover = now + DISCOVER_S
            if stop["streams"] and not bridge.streams:
                print("live: the graph runs: streamed topics are read from now on", flush=True)
                bridge.streams = True
            bridge.update()
            time.sleep(POLL_S if server.subscribed() else IDLE_POLL_S)
    finally:
        server.close()
        node.destroy_node()
        rclpy.try_shutdown()
    print(json.dumps({"live_forwarded": dict(server.forwarded), "wall_s": round(time.monotonic() - t0, 3),
                      "cpu_s": round(time.process_time(), 3)}), flush=True)
    return 0


def main(argv=None) -> int:
    from .rosenv import set_process_ros_env
    p = argparse.ArgumentParser(prog="python -m flip_tools.live_node", description=__doc__.split("\n\n")[0])
    p.add_argument("--port", type=port_arg, default=DEFAULT_PORT, help=f"0 = a free one (default {DEFAULT_PORT})")
    p.add_argument("--domain", type=int, help="ROS_DOMAIN_ID (default: the environment's)")
    p.add_argument("--duration", type=float, help="wall seconds (default: until SIGINT/SIGTERM)")
    p.add_argument("--hold-streams", action="store_true",
                   help="read the streamed topics only after SIGUSR1 (flip sends it once the graph runs)")
    p.add_argument("--rate", type=float, default=STREAM_RATE_HZ, metavar="HZ",
                   help=f"sim-time rate the per-step streams are forwarded at (default {STREAM_RATE_HZ:g}; "
                        f"0: every message)")
    a = p.parse_args(argv)
    set_process_ros_env()
    return serve(a.port, a.domain, duration=a.duration, hold_streams=a.hold_streams, rate_hz=a.rate)


if __name__ == "__main__":
    sys.exit(main())
