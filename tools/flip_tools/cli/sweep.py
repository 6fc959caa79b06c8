"""flip sweep: the landing rate of the paper's flips over perturbations of the simulated robot,
offline flips or `flip run`s through the node graph as Ray tasks (the sweep itself: flip_tools.sweep)."""
from __future__ import annotations

import argparse


def add_parser(sub) -> None:
    sp = sub.add_parser("sweep", help="landing rate of the paper's flips over perturbations of the simulated "
                                      "robot (offline flips or node-graph runs as Ray tasks; flip_tools.sweep)")
    sweep_opts(sp)
    sp.set_defaults(func=cmd_sweep)


def cmd_sweep(args) -> int:
    from flip_tools.sweep import cmd_sweep as sweep
    return sweep(args)


def sweep_opts(sp) -> None:
    """`flip sweep`'s arguments (the sweep itself: flip_tools.sweep)."""
    from flip_tools.perturb import FLIPS, KNOBS, ROBOT
    sp.epilog = ("flips (robot " + ROBOT + "):\n" + "\n".join(
        f"  {n}: {f.kind}, apex {f.apex} m, distance {f.distance} m, platform {f.platform} m"
        + (f", landing ground {f.ground_offset} m higher (not told to the planner)" if f.ground_offset else "")
        for n, f in FLIPS.items())
        + "\nknobs (applied to the simulator only):\n" + "\n".join(
        f"  {k} (default {d}): {about}" for k, (d, about) in KNOBS.items()))
    sp.formatter_class = argparse.RawDescriptionHelpFormatter
    sp.add_argument("--flips", nargs="+", choices=list(FLIPS), default=list(FLIPS), help="named flips (default all)")
    sp.add_argument("--grid", nargs="+", metavar="KNOB=V1,V2", help="every combination of these knob levels")
    sp.add_argument("--random", type=int, metavar="N", help="N samples drawn uniformly from the --range bounds")
    sp.add_argument("--range", nargs="+", metavar="KNOB=LO:HI", help="bounds of a knob for --random")
    sp.add_argument("--set", nargs="+", metavar="KNOB=V", help="a knob set alike in every sample (e.g. seconds=6)")
    sp.add_argument("--seed", type=int, default=0, help="seed of the random draws and the samples' noise (default 0)")
    sp.add_argument("--repeats", type=int, default=1,
                    help="grid: each point with seeds SEED .. SEED+N-1 (matters with noise knobs)")
    sp.add_argument("--workers", type=int, help="samples at a time (default: the CPUs Ray offers)")
    sp.add_argument("--address", metavar="HOST:PORT",
                    help="join this Ray cluster (default: Ray embedded on this machine, bound to 127.0.0.1)")
    sp.add_argument("--mode", choices=["offline", "graph"], default="offline",
                    help="offline (default): simulator, planner and controller in one process; graph: each "
                         "sample a `flip run` through the node graph (its own ROS domain, 2 CPUs a graph; "
                         "the noise knobs are refused)")
    sp.add_argument("--keep-bags", action="store_true", help="graph: keep each run's bag (DIR/runs/<id>/bag)")
    sp.add_argument("--out", help="output dir (default runs/sweep-<time>); a rerun with it resumes")
    sp.add_argument("--no-progress", action="store_true", help="no progress bar")
