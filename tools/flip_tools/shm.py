"""Fast DDS shared-memory files that no live process holds any more.

Fast DDS keeps each participant's segment and each listening port in /dev/shm (``fastrtps_<id>``,
``fastrtps_port<n>``, with ``sem.fastrtps_port<n>_mutex``) and holds an exclusive flock on the
companion ``<name>_el`` while it uses them. A process that is killed (SIGKILL) leaves them behind,
and later runs do not remove them. A file whose ``_el`` lock can be taken has no live owner: it is
removed with its companions (what Fast DDS's own ``fastdds shm clean`` does) -- unless it is younger than
``MIN_AGE_S``: a participant starting in another graph on the machine (a parallel test worker, a second
``flip``) creates its files before it takes their lock, and removing them in between cuts it off."""
from __future__ import annotations

import fcntl
import os
import time
from pathlib import Path

SHM_DIR = Path("/dev/shm")
PREFIX = "fastrtps_"
#: s: files modified more recently than this are left alone, whether their lock is held or not
MIN_AGE_S = 10.0


def _owner_gone(lock: Path) -> bool:
    try:
        fd = os.open(lock, os.O_RDWR)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return True
    finally:
        os.close(fd)


def _young(paths, min_age_s: float) -> bool:
    now = time.time()
    for f in paths:
        try:
            if now - f.stat().st_mtime < min_age_s:
                return True
        except OSError:
            pass
    return False


def clean_zombies(shm_dir: Path = SHM_DIR, min_age_s: float = MIN_AGE_S) -> dict:
    """Remove the Fast DDS files of dead owners, older than ``min_age_s``; returns {"files": n, "bytes": b}
    removed."""
    removed, size = 0, 0
    if not shm_dir.is_dir():
        return {"files": 0, "bytes": 0}
    for lock in sorted(shm_dir.glob(PREFIX + "*_el")):
        name = lock.name[:-len("_el")]
        if _young((lock, shm_dir / name), min_age_s) or not _owner_gone(lock):
            continue
        for f in (shm_dir / name, shm_dir / f"sem.{name}_mutex", lock):
            try:
                size += f.stat().st_size
                f.unlink()
                removed += 1
            except FileNotFoundError:
                pass
            except OSError:
                pass
    return {"files": removed, "bytes": size}
