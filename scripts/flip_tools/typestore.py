"""The rosbags typestore: ROS 2 Jazzy's standard types + flip_msgs registered from its .msg files.
No ROS import."""
from __future__ import annotations

import functools
import sys
from pathlib import Path

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from . import REPO_ROOT


def flip_msgs_dirs() -> list[Path]:
    """Where the flip_msgs .msg files are: the installed share dir first (what the running nodes
    were generated from, so it matches the bytes on the wire), then the source tree."""
    cands = [Path(sys.prefix) / "share" / "flip_msgs", REPO_ROOT / "ros_ws" / "src" / "flip_msgs"]
    return [c for c in cands if (c / "msg").is_dir()]


@functools.lru_cache(maxsize=1)
def flip_typestore():
    store = get_typestore(Stores.ROS2_JAZZY)
    dirs = flip_msgs_dirs()
    if not dirs:
        raise FileNotFoundError("flip_msgs .msg files not found (ros_ws/src/flip_msgs/msg or <venv>/share/flip_msgs/msg)")
    types = {}
    for f in sorted((dirs[0] / "msg").glob("*.msg")):
        types.update(get_types_from_msg(f.read_text(), f"flip_msgs/msg/{f.stem}"))
    store.register(types)
    return store
