"""A small Foxglove WebSocket client (the `websockets` package, no ROS): what the tests and
scripts/bench_live.py use to watch a `--live` graph as the Foxglove app would.

It offers both names of the protocol, as the app does: "foxglove.sdk.v1" (foxglove-sdk's servers)
and "foxglove.websocket.v1" (its first name; older servers). Server messages: JSON text frames
("serverInfo", "advertise", "unadvertise", ...) and binary frames whose first byte is the opcode;
opcode 1 is a message: subscription id (uint32), log time (uint64 ns), payload, little-endian.
"""
from __future__ import annotations

import json
import struct
import time
from dataclasses import dataclass

SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")
OP_MESSAGE_DATA = 0x01
_MESSAGE_HEADER = struct.Struct("<BIQ")


@dataclass(frozen=True)
class MessageData:
    subscription: int
    log_time: int       # ns
    payload: bytes      # the message's bytes as the server sent them (CDR for this project's channels)


def parse_binary(frame: bytes) -> MessageData | None:
    """A binary server frame: the message it carries, None for any other opcode."""
    if len(frame) < _MESSAGE_HEADER.size or frame[0] != OP_MESSAGE_DATA:
        return None
    _op, sub, t = _MESSAGE_HEADER.unpack_from(frame)
    return MessageData(sub, t, bytes(frame[_MESSAGE_HEADER.size:]))


class LiveClient:
    """One connection: the channels advertised so far (by topic), subscriptions by id."""

    def __init__(self, url: str, subprotocols=SUBPROTOCOLS, open_timeout: float = 10.0):
        from websockets.sync.client import connect
        self.ws = connect(url, subprotocols=list(subprotocols), open_timeout=open_timeout, max_size=None,
                          legacy=True)      # a connection object, closed by close()
        self.subprotocol = self.ws.subprotocol
        self.server_info: dict | None = None
        self.channels: dict[str, dict] = {}
        self.topic_of: dict[int, str] = {}
        self._next_sub = 1

    def receive(self, timeout: float):
        """The next frame, parsed: a dict (JSON op, advertisements recorded), a MessageData, or
        None when nothing came within ``timeout`` s."""
        try:
            frame = self.ws.recv(timeout=timeout)
        except TimeoutError:
            return None
        if isinstance(frame, str):
            msg = json.loads(frame)
            if msg.get("op") == "serverInfo":
                self.server_info = msg
            elif msg.get("op") == "advertise":
                for ch in msg["channels"]:
                    self.channels[ch["topic"]] = ch
            elif msg.get("op") == "unadvertise":
                gone = set(msg.get("channelIds", []))
                self.channels = {t: c for t, c in self.channels.items() if c["id"] not in gone}
            return msg
        return parse_binary(frame)

    def wait_for_channels(self, topics, timeout: float) -> dict[str, dict]:
        """Until every topic has been advertised (TimeoutError otherwise); their channels."""
        end = time.monotonic() + timeout
        while any(t not in self.channels for t in topics):
            left = end - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"not advertised after {timeout:.0f} s: "
                                   f"{sorted(t for t in topics if t not in self.channels)}; "
                                   f"advertised: {sorted(self.channels)}")
            self.receive(left)
        return {t: self.channels[t] for t in topics}

    def subscribe(self, topics) -> dict[int, str]:
        """Subscribe to the channels of these (advertised) topics; subscription id -> topic."""
        subs = []
        for topic in topics:
            sid, self._next_sub = self._next_sub, self._next_sub + 1
            self.topic_of[sid] = topic
            subs.append({"id": sid, "channelId": self.channels[topic]["id"]})
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
        return {s["id"]: self.topic_of[s["id"]] for s in subs}

    def messages(self, timeout: float):
        """(topic, MessageData) of every message that comes, until nothing has come for ``timeout`` s."""
        while (m := self.receive(timeout)) is not None:
            if isinstance(m, MessageData):
                yield self.topic_of.get(m.subscription), m

    def close(self) -> None:
        self.ws.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
