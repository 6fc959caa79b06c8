#!/usr/bin/env python3
"""Whole-graph speed: `flip run` with every node in its own process (lockstep), the real-time factor
measured over the stepping loop from the bag's /odom log times (wall-clock receive times, first step
to last; summary.json's real_time_factor), start-up reported apart, with the fraction of the steps'
/odom and /joint_states messages the bag holds (a lockstep run must lose none).  Prints a table, a
second one with the simulator's loop per step (its log: simulate, publish the state, wait for the
controller's command, planner holds, rest), and a third
with the CPU time per step of the simulator's and the controller's processes (their logs: main
thread, and the middleware's threads), which share one CPU: their sum against the wall time per step
tells whether the loop waits (wake-ups, hand-overs) or computes.  The machine's load average is
printed with it: on a shared 2-core machine the factor follows the other processes.

    .venv/bin/python scripts/bench_graph.py [--kind backflip] [--runs 2] [--robot NAME] [--motor-speed-scale 1]
        [--flywheel-torque NM] [--apex M] [--cpu-dma-latency US|off] [--lockstep-sched batch|other]
        [--zero-tick S] [--versus "FLIP OPTIONS"]

``--versus "OPTIONS"`` compares two configurations the way this machine needs it (its speed drifts
by ±10 % within an hour): each run is a pair, the runs as given (A) and then with OPTIONS added to
`flip`'s (B), one after the other; the last line gives B's factor against A's pair by pair.

``--zero-tick S`` measures the ceiling instead: S seconds of `flip stand` whose controller node
answers every state at once with zero torques (scripts/stand_ins/zero_tick_tsc_node.py), everything
else as in a run; the robot sinks to the ground meanwhile (more contacts for the simulator to step,
so the ceiling is a conservative one).

The runs hold the CPUs' wake-up latency at 0 us as `flip` does by default (flip_tools.cpu_latency:
an idle CPU polls, and the simulator's messages to the recorder on the other CPU wake it cheaply);
the table says whether it was held (it needs write access to /dev/cpu_dma_latency). The simulator and
controller run as SCHED_BATCH threads on their shared CPU, as `flip` does in lockstep
(``--lockstep-sched other`` to compare with the kernel's default policy).

(the design-study robot the flips land on: --robot cassie-legs3-fw260 --apex 1.3)
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FLIP = Path(__file__).resolve().parent / "flip"


ZERO_TICK_TSC = FLIP.parent / "stand_ins" / "zero_tick_tsc_node.py"


def one_run(kind: str, out: Path, extra: list[str], zero_tick_s: float = 0.0) -> dict:
    """One `flip run KIND`, or with ``zero_tick_s`` a `flip stand` of that many seconds whose
    controller answers at once (stand_ins/zero_tick_tsc_node.py): the graph's ceiling."""
    t0 = time.perf_counter()
    if zero_tick_s:
        cmd = ["stand", "--duration", str(zero_tick_s), "--exe", f"tsc={sys.executable} {ZERO_TICK_TSC}"]
        if "--apex" in extra:                     # a run's option a stand does not have
            i = extra.index("--apex")
            extra = extra[:i] + extra[i + 2:]
    else:
        cmd = ["run", kind]
    argv = [sys.executable, str(FLIP), *cmd, "--out", str(out), *extra]
    log = out.parent / f"{out.name}.flip.log"
    with open(log, "w") as f:
        rc = subprocess.run(argv, stdout=f, stderr=subprocess.STDOUT).returncode
    total = time.perf_counter() - t0
    if not (out / "summary.json").is_file():
        tail = "".join(log.read_text(errors="replace").splitlines(keepends=True)[-15:])
        raise SystemExit(f"bench_graph: {shlex.join(argv[1:])} exited {rc} without a summary; its last lines:\n{tail}")
    s = json.loads((out / "summary.json").read_text())
    run = json.loads((out / "run.json").read_text())
    tick = s.get("tsc_tick_us") or {}
    return {"loop": sim_loop_us(out / "logs" / "sim.log"),
            "cpu": {role: cpu_per_step_us(out / "logs" / f"{role}.log") for role in ("sim", "tsc")},
            "exit": rc, "outcome": s.get("outcome"), "graph_ready_s": run.get("graph_ready_s"),
            "first_state_wait_s": s.get("first_state_wait_s"),
            "sim_s": s.get("sim_duration_s"), "clock_wall_s": s.get("clock_wall_s"),
            "rtf": s.get("real_time_factor"), "cpu_latency": latency_cell(run.get("cpu_dma_latency")),
            "sched": run.get("lockstep_sched", "?"), "tick_med": tick.get("median"), "tick_p99": tick.get("p99"),
            "recorded": recorded_fraction(out / "bag"), "load": os.getloadavg()[0], "process_total_s": total}


def latency_cell(info) -> str:
    """run.json's cpu_dma_latency as a table cell: '0 us' when held, 'not held' / 'off' otherwise."""
    if not info:
        return "?"
    if info.get("held"):
        return f"{info['requested_us']} us"
    return "off" if info.get("requested_us") is None else "not held"


def log_line_us(log: Path, marker: str) -> dict:
    """{name: value} from the last '<marker>name value, name value, ...' line of a node's log."""
    try:
        text = log.read_text(errors="replace")
    except OSError:
        return {}
    lines = [ln for ln in text.splitlines() if marker in ln]
    if not lines:
        return {}
    out = {}
    for part in lines[-1].split(marker, 1)[1].split(", "):
        name, _, val = part.rpartition(" ")
        try:
            out[name] = float(val)
        except ValueError:
            pass
    return out


def sim_loop_us(log: Path) -> dict:
    """{part: mean us per step} from sim_node's 'loop per step (mean us): name value, ...' line."""
    return log_line_us(log, "loop per step (mean us): ")


def cpu_per_step_us(log: Path) -> dict:
    """{'main thread': us, 'other threads': us} per step from a node's 'cpu per step (mean us): ...' line
    (flip_transport.lockstep.cpu_per_step_line)."""
    return log_line_us(log, "cpu per step (mean us): ")


def recorded_fraction(bag: Path) -> str:
    """'odom/joint_states' fractions of the stepped steps (from the first to the last step that
    /clock, /odom or /joint_states carries) that the bag holds, and the steps either topic misses
    (up to three each, 'last' for the final step: a simulator stopped between its /odom and its
    /joint_states)."""
    import numpy as np
    from flip_tools.bag import load_bag
    data = load_bag(bag, ["/clock", "/odom", "/joint_states"])
    steps = {t: np.unique(np.round(data[t][k] / 0.0005)).astype(int)
             for t, k in (("/clock", "sim_t"), ("/odom", "t"), ("/joint_states", "t"))}
    lo, hi = min(v.min() for v in steps.values()), max(v.max() for v in steps.values())
    n = hi - lo + 1
    out = "/".join(f"{len(steps[t]) / n:.4f}" for t in ("/odom", "/joint_states"))
    missing = []
    for t in ("/odom", "/joint_states"):
        gone = np.setdiff1d(np.arange(lo, hi + 1), steps[t])
        if gone.size:
            shown = ", ".join("last" if k == hi else str(k) for k in gone[:3])
            missing.append(f"{t[1:]} {gone.size} missing: {shown}{' ...' if gone.size > 3 else ''}")
    return out + (f" ({'; '.join(missing)})" if missing else "")


def paired_line(rows: list[dict]) -> str:
    """'B against A, pair by pair: ...' from rows of alternating configs (A, B, A, B, ...): each
    pair's difference of the real-time factor, in how many B is faster, and the median difference."""
    pairs = [(a["rtf"], b["rtf"]) for a, b in zip(rows[0::2], rows[1::2]) if a["rtf"] and b["rtf"]]
    if not pairs:
        return "B against A: no pair with both factors"
    d = [b - a for a, b in pairs]
    return (f"B against A, pair by pair: {', '.join(f'{x:+.3f}' for x in d)}; B faster in "
            f"{sum(x > 0 for x in d)} of {len(d)}, median difference {statistics.median(d):+.3f}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kind", default="backflip", choices=["backflip", "frontflip", "hop"])
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--robot", help="named robot (flip run --robot)")
    ap.add_argument("--motor-speed-scale", type=float)
    ap.add_argument("--flywheel-torque", type=float)
    ap.add_argument("--apex", type=float)
    ap.add_argument("--cpu-dma-latency", default="0", metavar="US|off",
                    help="flip's --cpu-dma-latency (default 0: held at 0 us where this process may)")
    ap.add_argument("--lockstep-sched", default="batch", choices=["batch", "other"],
                    help="flip's --lockstep-sched: the simulator's and controller's scheduling policy "
                         "(default batch, flip's own default in lockstep)")
    ap.add_argument("--zero-tick", type=float, metavar="S", default=0.0,
                    help="instead: S seconds of `flip stand` with a controller that answers at once "
                         "(zero torques): the factor the graph would reach with an instant controller")
    ap.add_argument("--versus", metavar="\"OPTIONS\"",
                    help="flip options of a second configuration (B), e.g. \"--lockstep-sched other\": "
                         "each run is then a pair, A then B")
    a = ap.parse_args()
    extra = ["--cpu-dma-latency", a.cpu_dma_latency, "--lockstep-sched", a.lockstep_sched]
    for flag, val in (("--robot", a.robot), ("--motor-speed-scale", a.motor_speed_scale), ("--flywheel-torque", a.flywheel_torque),
                      ("--apex", a.apex)):
        if val:
            extra += [flag, str(val)]
    configs = [("A", extra)] + ([("B", extra + shlex.split(a.versus))] if a.versus else [])
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(a.runs):
            for name, flags in configs:
                rows.append({**one_run(a.kind, Path(tmp) / f"run{i}{name}", flags, a.zero_tick), "config": name})
    label = [f"{i // len(configs)}{r['config']}" if a.versus else str(i) for i, r in enumerate(rows)]
    if a.versus:
        print(f"A: the options given; B: with {a.versus} added")
    if a.zero_tick:
        print(f"flip stand {a.zero_tick:g} s with a zero-cost controller tick (stand_ins/zero_tick_tsc_node.py): "
              "every node its own process, lockstep at 2 kHz sim time")
    else:
        print(f"flip run {a.kind}: every node its own process, lockstep at 2 kHz sim time")
    print("| run | outcome | graph ready s | first state answered after s | sim s | stepping wall s | RTF (stepping) "
          "| tsc tick median/p99 us | recorded odom/joint_states | CPU wake-up latency | sched | load avg "
          "| whole command s |")
    print("|-----|---------|---------------|------------------------------|-------|-----------------|----------------"
          "|------------------------|----------------------------|---------------------|-------|----------"
          "|-----------------|")
    for i, r in enumerate(rows):
        print(f"| {label[i]} | {r['outcome']} | {r['graph_ready_s']} | {r['first_state_wait_s']} | {r['sim_s']} | "
              f"{r['clock_wall_s']} | {r['rtf']} | "
              f"{r['tick_med']}/{r['tick_p99']} | {r['recorded']} | {r['cpu_latency']} | {r['sched']} | {r['load']:.1f} | {r['process_total_s']:.1f} |")
    parts = list(dict.fromkeys(n for r in rows for n in r["loop"]))
    if parts:
        print()
        print("simulator loop per step, mean us (sim_node's log; wait for command = the controller's tick, "
              "its messages and the hand-overs)")
        print("| run | " + " | ".join(parts) + " | total |")
        print("|-----|" + "|".join("-" * (len(n) + 2) for n in parts) + "|-------|")
        for i, r in enumerate(rows):
            print(f"| {label[i]} | " + " | ".join(f"{r['loop'].get(n, float('nan')):.0f}" for n in parts)
                  + f" | {sum(r['loop'].values()):.0f} |")
    if any(r["cpu"]["sim"] and r["cpu"]["tsc"] for r in rows):
        print()
        print("CPU time per step, mean us (each node's log: its main thread, and its other threads = the "
              "middleware's; the two nodes share one CPU, so the sum against the loop's wall time per step "
              "is how busy that CPU is)")
        print("| run | sim main | sim other | tsc main | tsc other | sum | loop wall | busy |")
        print("|-----|----------|-----------|----------|-----------|-----|-----------|------|")
        for i, r in enumerate(rows):
            c = [r["cpu"][n].get(k, float("nan")) for n in ("sim", "tsc") for k in ("main thread", "other threads")]
            wall = sum(r["loop"].values())
            print(f"| {label[i]} | " + " | ".join(f"{x:.0f}" for x in c) + f" | {sum(c):.0f} | {wall:.0f} | "
                  f"{100 * sum(c) / wall if wall else float('nan'):.0f} % |")
    for name, _ in configs:
        rtf = [r["rtf"] for r in rows if r["rtf"] and r["config"] == name]
        if rtf:
            print(("" if not a.versus else f"{name}: ")
                  + f"real-time factor over the stepping loop: median {statistics.median(rtf):.3f}, best {max(rtf):.3f}, "
                  f"worst {min(rtf):.3f}" + (" (a ceiling: no controller work)" if a.zero_tick else " (target >= 1.5)"))
    if a.versus:
        print(paired_line(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
