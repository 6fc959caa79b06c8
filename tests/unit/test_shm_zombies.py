"""flip_tools.shm.clean_zombies on a directory of Fast DDS-like files: a file whose lock nobody holds is
removed once it is older than MIN_AGE_S, a younger one is left (a participant starting elsewhere on the
machine makes its files before it locks them), and one whose lock is held is kept at any age."""
import fcntl
import os
import time

from flip_tools.shm import MIN_AGE_S, clean_zombies


def _segment(d, name, age_s):
    t = time.time() - age_s
    for f in (d / name, d / f"{name}_el"):
        f.write_bytes(b"x" * 64)
        os.utime(f, (t, t))


def test_unlocked_files_go_once_old_young_and_held_ones_stay(tmp_path):
    _segment(tmp_path, "fastrtps_old", 3 * MIN_AGE_S)
    _segment(tmp_path, "fastrtps_new", 0.0)
    _segment(tmp_path, "fastrtps_held", 3 * MIN_AGE_S)
    fd = os.open(tmp_path / "fastrtps_held_el", os.O_RDWR)
    fcntl.flock(fd, fcntl.LOCK_EX)          # a live owner's lock (another open file description)
    try:
        report = clean_zombies(tmp_path)
    finally:
        os.close(fd)
    left = sorted(f.name for f in tmp_path.iterdir())
    assert left == ["fastrtps_held", "fastrtps_held_el", "fastrtps_new", "fastrtps_new_el"]
    assert report == {"files": 2, "bytes": 128}
    assert clean_zombies(tmp_path, min_age_s=0.0)["files"] == 4      # no age bound: both lockless ones
