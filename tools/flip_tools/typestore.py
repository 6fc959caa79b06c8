"""The rosbags typestore: ROS 2 Jazzy's standard types + the workspace's interface packages
(flip_msgs, and tf2_msgs/msg/TFMessage of /tf and /tf_static) registered from their .msg files.
No ROS import."""
from __future__ import annotations

import functools
import sys
from pathlib import Path

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from . import REPO_ROOT

#: interface packages of the workspace whose messages the recorder writes and the bag reader reads
WORKSPACE_MSG_PACKAGES = ("flip_msgs", "tf2_msgs")


def msg_dirs(package: str = "flip_msgs") -> list[Path]:
    """Where an interface package's .msg files are: the installed share dir first (what the running
    nodes were generated from, so it matches the bytes on the wire), then the source tree."""
    cands = [Path(sys.prefix) / "share" / package, REPO_ROOT / "ros_ws" / "src" / package]
    return [c for c in cands if (c / "msg").is_dir()]


@functools.lru_cache(maxsize=1)
def flip_typestore():
    """Jazzy's types with every WORKSPACE_MSG_PACKAGES message registered (a definition the store
    already has, e.g. tf2_msgs', must be the same)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for pkg in WORKSPACE_MSG_PACKAGES:
        dirs = msg_dirs(pkg)
        if not dirs:
            raise FileNotFoundError(f"{pkg} .msg files not found "
                                    f"(ros_ws/src/{pkg}/msg or <venv>/share/{pkg}/msg)")
        for f in sorted((dirs[0] / "msg").glob("*.msg")):
            types.update(get_types_from_msg(f.read_text(), f"{pkg}/msg/{f.stem}"))
    store.register(types)
    return store
