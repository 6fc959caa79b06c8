"""A two-node Ray cluster on this machine, and a command run against it: for tests/offline/test_sweep.py.

    python tests/ray_cluster.py TEMP_DIR -- COMMAND ...   (COMMAND's "{address}" becomes HOST:PORT)

Run it in a network namespace of its own with only the loopback interface (``unshare -n``; it sets
``lo`` up): a Linux Ray node takes 127.0.0.1 for its outward address only when no other interface
exists, so every server of both nodes binds to 127.0.0.1.  The head (``--node-ip-address=127.0.0.1``)
and a second node joining it (``--address=127.0.0.1:PORT``) get one CPU each; both are stopped by
their process ids when the command ends (``ray stop`` would stop every Ray process of the machine).
Exit status: the command's; 3 when the cluster did not come up.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

RAY = str(Path(sys.executable).parent / "ray")
PORT = 6380                     # the namespace is empty: any port is free


def alive_nodes(address: str) -> int:
    code = ("import ray; ray.init(address=%r, logging_level='ERROR'); "
            "print(sum(n['Alive'] for n in ray.nodes()))" % address)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    return int(r.stdout.strip().splitlines()[-1]) if r.returncode == 0 and r.stdout.strip() else 0


def start(args: list[str], log: Path) -> subprocess.Popen:
    return subprocess.Popen([RAY, "start", "--block", "--num-cpus=1", "--disable-usage-stats", *args],
                            stdout=open(log, "w"), stderr=subprocess.STDOUT)


def main(argv: list[str]) -> int:
    temp_dir, command = argv[0], argv[argv.index("--") + 1:]
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
    os.environ.update(RAY_AUTH_MODE="token", RAY_USAGE_STATS_ENABLED="0")
    address = f"127.0.0.1:{PORT}"
    procs = []
    try:
        procs.append(start(["--head", "--node-ip-address=127.0.0.1", f"--port={PORT}", "--include-dashboard=false",
                            f"--temp-dir={temp_dir}"], Path(temp_dir) / "head.log"))
        time.sleep(3)
        procs.append(start([f"--address={address}"], Path(temp_dir) / "node.log"))
        deadline = time.monotonic() + 90
        while alive_nodes(address) < 2:
            if time.monotonic() > deadline or any(p.poll() is not None for p in procs):
                print("ray_cluster: the two nodes did not come up", file=sys.stderr)
                return 3
            time.sleep(1)
        return subprocess.run([c.replace("{address}", address) for c in command]).returncode
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in reversed(procs):
            try:
                p.wait(timeout=60)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
