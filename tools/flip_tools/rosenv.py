"""ROS environment helpers shared by the launcher, the recorder and the tests.

- DomainClaim: pick a ROS_DOMAIN_ID nobody else on this machine is using *through this tool*
  (an flock-ed file per domain under /tmp), so parallel tests/runs do not see each other.
- node_env(): the environment every node process gets.
- CONTRACT_TOPICS: the topic/type/QoS table of docs/architecture.md.
- message_class(): 'pkg/msg/Name' -> the rclpy message class (no rosidl_runtime_py in the venv).
"""
from __future__ import annotations

import fcntl
import importlib
import os
from dataclasses import dataclass
from pathlib import Path

DOMAIN_MIN, DOMAIN_MAX = 1, 100
LOCK_DIR = Path(os.environ.get("FLIP_DOMAIN_LOCK_DIR", "/tmp/somersault-ros-domains"))


class DomainClaim:
    """Holds an exclusive flock on /tmp/somersault-ros-domains/<id>.lock while alive."""

    def __init__(self, domain_id: int, fd: int | None):
        self.domain_id = domain_id
        self._fd = fd

    def release(self) -> None:
        if self._fd is not None:
            try:
                fcntl.flock(self._fd, fcntl.LOCK_UN)
                os.close(self._fd)
            finally:
                self._fd = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()

    def __del__(self):
        try:
            self.release()
        except Exception:
            pass


def claim_domain(preferred: int | None = None, salt: int = 0) -> DomainClaim:
    """Claim a free domain id in DOMAIN_MIN..DOMAIN_MAX.

    `preferred` (e.g. an explicit --domain or ROS_DOMAIN_ID) is used as is (locked if free, not
    locked otherwise). Otherwise the search starts at an offset derived from pid and `salt`
    (e.g. a per-test counter or the pytest-xdist worker) and takes the first id whose lock file
    is free.
    """
    LOCK_DIR.mkdir(parents=True, exist_ok=True)
    try:
        os.chmod(LOCK_DIR, 0o1777)
    except OSError:
        pass
    n = DOMAIN_MAX - DOMAIN_MIN + 1
    if preferred is not None:
        fd = _try_lock(preferred)
        return DomainClaim(preferred, fd)
    start = (os.getpid() * 7 + salt * 13) % n
    for k in range(n):
        dom = DOMAIN_MIN + (start + k) % n
        fd = _try_lock(dom)
        if fd is not None:
            return DomainClaim(dom, fd)
    raise RuntimeError(f"no free ROS domain id in {DOMAIN_MIN}..{DOMAIN_MAX} (locks in {LOCK_DIR})")


def _try_lock(dom: int) -> int | None:
    path = LOCK_DIR / f"{dom}.lock"
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())
    return fd


def node_env(domain_id: int, extra: dict | None = None, base: dict | None = None) -> dict:
    """Environment of a node process: the caller's env + an isolated domain on loopback."""
    env = dict(os.environ if base is None else base)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_LOCALHOST_ONLY", None)  # deprecated in Jazzy, conflicts with the range
    env.setdefault("MUJOCO_GL", "egl")
    env["PYTHONUNBUFFERED"] = "1"
    if extra:
        env.update({k: str(v) for k, v in extra.items()})
    return env


def set_process_ros_env() -> None:
    """For a process that calls rclpy.init itself (flip, pytest): loopback discovery only, and the
    Fast DDS profile the launcher gives the graph's nodes (its discovery announcements: without it
    this process saw the graph ~3 s late)."""
    from .fastdds import PROFILES_ENV, fastdds_profile_file
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.pop("ROS_LOCALHOST_ONLY", None)
    os.environ.setdefault("MUJOCO_GL", "egl")
    os.environ.setdefault(PROFILES_ENV, fastdds_profile_file())


# --- the contract table (docs/architecture.md) --------------------------------------------------
@dataclass(frozen=True)
class TopicSpec:
    name: str
    msgtype: str          # rosbags / ROS 2 form: pkg/msg/Name
    reliable: bool
    transient_local: bool
    depth: int            # publisher depth in the contract


CONTRACT_TOPICS: dict[str, TopicSpec] = {t.name: t for t in [
    TopicSpec("/clock", "rosgraph_msgs/msg/Clock", False, False, 1),
    TopicSpec("/joint_states", "sensor_msgs/msg/JointState", False, False, 1),
    TopicSpec("/odom", "nav_msgs/msg/Odometry", False, False, 1),
    TopicSpec("/motor_command", "flip_msgs/msg/MotorCommand", False, False, 1),
    TopicSpec("/contact_events", "flip_msgs/msg/ContactEvent", True, True, 10),
    TopicSpec("/fslip/reference", "flip_msgs/msg/FlipReference", True, True, 5),
    TopicSpec("/robot_description", "std_msgs/msg/String", True, True, 1),        # URDF
    TopicSpec("/robot_description_mjcf", "std_msgs/msg/String", True, True, 1),   # MJCF
    TopicSpec("/tf", "tf2_msgs/msg/TFMessage", True, False, 100),
    TopicSpec("/tf_static", "tf2_msgs/msg/TFMessage", True, True, 1),
    TopicSpec("/left_foot/wrench", "geometry_msgs/msg/WrenchStamped", False, False, 1),
    TopicSpec("/right_foot/wrench", "geometry_msgs/msg/WrenchStamped", False, False, 1),
    TopicSpec("/fslip/com_path", "nav_msgs/msg/Path", True, True, 1),
    TopicSpec("/fslip/targets", "visualization_msgs/msg/MarkerArray", True, True, 1),
]}


def contract_qos(name: str, depth: int | None = None):
    """rclpy QoSProfile of a contract topic (as its publisher offers it)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    t = CONTRACT_TOPICS[name]
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth if depth is not None else t.depth,
        reliability=ReliabilityPolicy.RELIABLE if t.reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if t.transient_local else DurabilityPolicy.VOLATILE,
    )


def message_class(msgtype: str):
    """'pkg/msg/Name' (or 'pkg/Name') -> rclpy message class."""
    parts = msgtype.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    pkg, sub, name = parts
    return getattr(importlib.import_module(f"{pkg}.{sub}"), name)
