"""flip removes the Fast DDS shared-memory files that killed processes leave in /dev/shm, and
nothing a live process holds (flip_tools.shm.clean_zombies, called when a graph closes)."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from flip_tools.shm import SHM_DIR, clean_zombies

NODE = ("import rclpy, time; from std_msgs.msg import String; rclpy.init(); n = rclpy.create_node('shm_probe'); "
        "n.create_publisher(String, '/shm_probe', 10); print('up', flush=True); time.sleep(120)")


def start_node(domain):
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    p = subprocess.Popen([sys.executable, "-c", NODE], env=env, stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "up"
    time.sleep(1.0)
    return p


def segments():
    """Participant segments (not ports, not their _el lock files)."""
    return {f.name for f in SHM_DIR.glob("fastrtps_*")
            if not f.name.startswith("fastrtps_port") and not f.name.endswith("_el")}


def _age(names, by_s=60.0):
    """Files of these segments (and their locks) as if made ``by_s`` ago: clean_zombies leaves younger
    ones alone (flip_tools.shm.MIN_AGE_S)."""
    t = time.time() - by_s
    for n in names:
        for f in (SHM_DIR / n, SHM_DIR / f"{n}_el"):
            if f.exists():
                os.utime(f, (t, t))


def held_by(pid):
    """The participant segments whose ``_el`` lock process ``pid`` holds (/proc/locks: its flocks by
    inode), whatever other processes on the machine (a parallel test worker's graph) make or map."""
    inodes = set()
    for line in Path("/proc/locks").read_text().splitlines():
        f = line.split()
        if len(f) >= 6 and f[1] == "FLOCK" and f[4] == str(pid):
            inodes.add(int(f[5].split(":")[-1]))
    return {n for n in segments() if (SHM_DIR / f"{n}_el").exists()
            and (SHM_DIR / f"{n}_el").stat().st_ino in inodes}


def test_files_of_a_killed_process_are_removed_those_of_a_live_one_kept():
    clean_zombies()
    victim = start_node(93)
    mine = held_by(victim.pid)
    assert mine, "the node made no shared-memory segment"
    victim.send_signal(signal.SIGKILL)
    victim.wait(10)
    assert mine <= segments()                               # left behind by the kill
    alive = start_node(94)
    try:
        theirs = held_by(alive.pid)
        assert theirs and not (theirs & mine)
        _age(mine | theirs)
        report = clean_zombies()
        assert not (mine & segments()) and report["files"] >= 2 * len(mine) and report["bytes"] > 0
        assert theirs <= segments()                          # held by a live process: kept
        assert all(Path(SHM_DIR, f"{s}_el").exists() for s in theirs)
    finally:
        alive.kill()
        alive.wait(10)
    clean_zombies()
    assert not (theirs & segments())
