#!/usr/bin/env python3
"""The recorder's cost of zstd chunks, offline: a bag's messages written again through rosbags' MCAP
writer as flip_tools.recorder writes them, uncompressed and zstd-compressed, timed (CPU seconds of
this process) and sized.

    .venv/bin/python scripts/bench_bag_compression.py runs/demo/bag [--repeat 3]
"""
import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

from rosbags.rosbag2 import CompressionFormat, CompressionMode, Reader, StoragePlugin, Writer


def write(messages, conns, out: Path, zstd: bool) -> tuple[float, int]:
    w = Writer(out, version=9, storage_plugin=StoragePlugin.MCAP)
    if zstd:
        w.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    w.open()
    new = {c.id: w.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, rihs01=c.digest,
                                  offered_qos_profiles=c.ext.offered_qos_profiles) for c in conns}
    t0 = time.process_time()
    for cid, t, data in messages:
        w.write(new[cid], t, data)
    w.close()
    cpu = time.process_time() - t0
    return cpu, sum(f.stat().st_size for f in out.glob("*.mcap"))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("bag")
    p.add_argument("--repeat", type=int, default=3)
    a = p.parse_args()
    with Reader(a.bag) as r:
        conns = list(r.connections)
        messages = [(c.id, t, bytes(m)) for c, t, m in r.messages()]
    print(f"{a.bag}: {len(messages)} messages, {sum(len(m[2]) for m in messages) / 1e6:.1f} MB of CDR")
    tmp = Path(tempfile.mkdtemp())
    try:
        for i in range(a.repeat):
            for zstd in (False, True):
                out = tmp / f"{i}-{int(zstd)}"
                cpu, size = write(messages, conns, out, zstd)
                print(f"{'zstd' if zstd else 'none'}: {cpu:.2f} s CPU, {size / 1e6:.1f} MB")
                shutil.rmtree(out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
