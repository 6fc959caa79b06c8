#!/usr/bin/env python3
"""What --live costs the lockstep: the same `flip` command run back to back without --live, with
--live and nobody watching, and with --live and a client subscribed to every channel (as a Foxglove
layout that shows everything would be), interleaved (the order rotated each round), REPEAT rounds; prints each run's real-time
factor (sim time / wall time of the bag, summary.json), the simulator's and the controller's CPU per
lockstep step (their logs: an extra reader of the 2 kHz topics costs the publisher there, whatever
else the machine runs), the load average before the run, and what the client received.

    .venv/bin/python scripts/bench_live.py --repeat 3 -- stand --duration 10
    .venv/bin/python scripts/bench_live.py --repeat 2 -- run backflip --robot cassie-legs3-fw260 --apex 1.3 --settle 8
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

FLIP = Path(__file__).resolve().parent / "flip"
MODES = ("off", "live", "live+client")


def watch_everything(proc: subprocess.Popen, counts: dict) -> None:
    """Read flip's output until its live URL, then subscribe to every channel as it is advertised
    and count the messages until the server goes away."""
    from flip_tools.live_client import LiveClient
    url = None
    for line in proc.stdout:
        m = re.match(r"live: (ws://\S+) ", line)
        if m:
            url = m.group(1)
            break
    threading.Thread(target=lambda: [None for _ in proc.stdout], daemon=True).start()   # drain
    if url is None:
        return
    try:
        with LiveClient(url) as c:
            subscribed = set()
            while True:
                m = c.receive(timeout=60)
                if m is None:
                    return
                new = [t for t in c.channels if t not in subscribed]
                if new:
                    c.subscribe(new)
                    subscribed.update(new)
                if hasattr(m, "payload"):
                    topic = c.topic_of.get(m.subscription)
                    counts[topic] = counts.get(topic, 0) + 1
    except Exception:  # noqa: BLE001 - the server closes the connection at the run's end
        return


def run_once(flip_args: list[str], mode: str, out: Path) -> dict:
    cmd = [sys.executable, str(FLIP), *flip_args, "--out", str(out)]
    if mode != "off":
        cmd += ["--live", "--live-port", "0"]
    counts: dict = {}
    load = os.getloadavg()[0]
    t0, cpu0 = time.monotonic(), time.process_time()
    if mode == "live+client":
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        watch_everything(proc, counts)
        rc = proc.wait()
    else:
        rc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode
    s = json.loads((out / "summary.json").read_text())
    return {"mode": mode, "exit": rc, "outcome": s.get("outcome"), "rtf": s.get("real_time_factor"),
            "sim_s": s.get("sim_duration_s"), "tick_median_us": (s.get("tsc_tick_us") or {}).get("median"),
            "wall_s": round(time.monotonic() - t0, 1), "client_messages": sum(counts.values()),
            "client_cpu_s": round(time.process_time() - cpu0, 2), "live_cpu_s": live_cpu(out),
            "load": round(load, 2), "sim_cpu_us": cpu_per_step(out / "logs" / "sim.log"),
            "tsc_cpu_us": cpu_per_step(out / "logs" / "tsc.log")}


def cpu_per_step(log: Path) -> str | None:
    """'main+other' µs of CPU per step, from the node's 'cpu per step (mean us)' log line."""
    try:
        m = re.search(r"cpu per step \(mean us\): main thread (\d+), other threads (\d+)", log.read_text())
    except OSError:
        return None
    return f"{m.group(1)}+{m.group(2)}" if m else None


def live_cpu(out: Path) -> float | None:
    """CPU seconds of the live process, from the JSON line it prints at its end (logs/live.log)."""
    try:
        for line in (out / "logs" / "live.log").read_text().splitlines():
            if line.startswith('{"live_forwarded"'):
                return json.loads(line)["cpu_s"]
    except OSError:
        pass
    return None


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--repeat", type=int, default=2)
    p.add_argument("--out", default="/tmp/bench_live")
    p.add_argument("--modes", nargs="+", choices=MODES, default=list(MODES), help="default: all three")
    p.add_argument("flip_args", nargs="+", help="the flip command after --, without --out")
    a = p.parse_args()
    rows = []
    print(f"{'round':>5} {'mode':>12} {'load':>5} {'exit':>4} {'outcome':>10} {'sim s':>6} {'RTF':>6} {'tick us':>7} "
          f"{'sim cpu/step':>12} {'tsc cpu/step':>12} {'wall s':>6} {'client msgs':>11} {'client cpu s':>12} "
          f"{'live cpu s':>10}", flush=True)
    for i in range(a.repeat):
        # each round in another order (off, live, live+client; then live, live+client, off; ...): a
        # machine that changes pace within a round would otherwise favour one mode
        modes = [m for m in MODES if m in a.modes]
        for mode in modes[i % len(modes):] + modes[:i % len(modes)]:
            r = run_once(a.flip_args, mode, Path(a.out) / f"{mode.replace('+', '-')}-{i}")
            rows.append(r)
            print(f"{i:>5} {mode:>12} {r['load']:>5} {r['exit']:>4} {str(r['outcome']):>10} {r['sim_s']:>6} "
                  f"{r['rtf']:>6} {r['tick_median_us']:>7} {str(r['sim_cpu_us']):>12} {str(r['tsc_cpu_us']):>12} "
                  f"{r['wall_s']:>6} {r['client_messages']:>11} {r['client_cpu_s']:>12} {str(r['live_cpu_s']):>10}",
                  flush=True)
    for mode in a.modes:
        rtfs = [r["rtf"] for r in rows if r["mode"] == mode and r["rtf"]]
        if rtfs:
            print(f"{mode:>12}: RTF mean {sum(rtfs) / len(rtfs):.3f} (min {min(rtfs):.3f}, max {max(rtfs):.3f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
