#!/usr/bin/env python3
"""Planner timing: cold jumping solves (median over --cold runs, a fresh initial guess each time; the
NLP is built once per process and reused, its build time reported separately) for backflip,
frontflip (--distance 1.0) and hop, and warm landing re-solves (median over --warm perturbed
post-impact states, warm-started from the nominal touch-down solution).

    .venv/bin/python scripts/bench_planner.py [--flywheel I] [--cold 5] [--warm 10]
"""
import argparse
import statistics
import sys
import time

import numpy as np

from fslip_planner import jumping as Jm
from fslip_planner import plan as P


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--flywheel", default="I")
    ap.add_argument("--cold", type=int, default=5)
    ap.add_argument("--warm", type=int, default=10)
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    robot = P._Robot.get(a.flywheel)
    t_robot = time.perf_counter() - t0
    rows = []
    t0 = time.perf_counter()
    Jm.JumpingProblem(robot.params, robot.L0)
    t_build = time.perf_counter() - t0
    apex = P.default_apex(a.flywheel)
    for kind, d in (("backflip", 0.0), ("frontflip", 1.0), ("hop", 0.0)):
        times, its = [], []
        for _ in range(a.cold):
            r = P.plan_flip(kind, apex_height=apex, forward_distance=d, flywheel=a.flywheel)
            times.append(r.figures["solve_time"])
            its.append(r.figures["iterations"])
        rows.append((f"jumping {kind}" + (f" d={d:g}" if d else ""), "cold", statistics.median(times),
                     max(times), statistics.median(its)))
    s = P.FlipSession("backflip", apex_height=apex, flywheel=a.flywheel)
    s.jumping_reference()
    lo = s.result.lift_off
    rng = np.random.default_rng(0)
    times, its = [], []
    for _ in range(a.warm):
        st = P.MeasuredState(0.0, np.array([0.0, 0.0, 1.0]),
                             np.array([lo["xdot"] + rng.normal(0, 0.15), 0.0, -lo["zdot"] + rng.normal(0, 0.15)]),
                             lo["momentum"] * (1 + rng.normal(0, 0.1)), -lo["beta"], 0.0)
        t0 = time.perf_counter()
        s._landing.solve(s._touchdown_state(st), warm=True)
        times.append(time.perf_counter() - t0)
        its.append(s._landing.warm.stats()["iter_count"])
    rows.append(("landing backflip (perturbed)", "warm", statistics.median(times), max(times),
                 statistics.median(its)))
    print(f"flywheel {a.flywheel}, apex {apex:.2f} m; robot model {t_robot:.2f} s, jumping NLP build {t_build:.2f} s (the first solve also sets up IPOPT: see max)")
    print(f"{'problem':34s} {'start':5s} {'median ms':>10s} {'max ms':>8s} {'iters':>6s}")
    for name, kind, med, mx, it in rows:
        print(f"{name:34s} {kind:5s} {1e3 * med:10.1f} {1e3 * mx:8.1f} {it:6.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
