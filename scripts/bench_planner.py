#!/usr/bin/env python3
"""Planner timing: cold jumping solves (median over --cold runs, a fresh initial guess each time; the
NLP is built once per process and reused, its build time reported separately) for backflip,
frontflip (--distance 1.0) and hop, and warm landing re-solves (median over --warm perturbed
post-impact states, each warm-started from the nearest state solved before: the nominal touch-down's
and the earlier perturbed ones).

    .venv/bin/python scripts/bench_planner.py [--flywheel I] [--motor-speed-scale X] [--flywheel-torque NM]
        [--apex M] [--platform M] [--cold 5] [--warm 10]

A rejected request is reported with the limit that binds.  The grid of requests under several BLAS
kernels: scripts/bench_planner_grid.py.
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
    ap.add_argument("--motor-speed-scale", type=float, default=1.0)
    ap.add_argument("--flywheel-torque", type=float, default=None)
    ap.add_argument("--apex", type=float, default=None, help="COM apex, m (default: the planner's)")
    ap.add_argument("--platform", type=float, default=0.0, help="landing ground this much lower, m")
    ap.add_argument("--cold", type=int, default=5)
    ap.add_argument("--warm", type=int, default=10)
    a = ap.parse_args(argv)
    robot_kw = dict(flywheel=a.flywheel, motor_speed_scale=a.motor_speed_scale, flywheel_torque=a.flywheel_torque)
    t0 = time.perf_counter()
    robot = P._Robot.get(a.flywheel, a.motor_speed_scale, a.flywheel_torque)
    t_robot = time.perf_counter() - t0
    rows = []
    t0 = time.perf_counter()
    Jm.JumpingProblem(robot.params, robot.L0)
    t_build = time.perf_counter() - t0
    apex = a.apex or P.default_apex(a.flywheel, a.motor_speed_scale, a.flywheel_torque)
    session_kind = None
    for kind, d in (("backflip", 0.0), ("frontflip", 1.0), ("hop", 0.0)):
        times, its, why = [], [], None
        for _ in range(a.cold):
            try:
                r = P.plan_flip(kind, apex_height=apex, forward_distance=d, platform_height=a.platform, **robot_kw)
            except P.InfeasibleRequest as e:
                why = e
                break
            times.append(r.figures["solve_time"])
            its.append(r.figures["iterations"])
        name = f"jumping {kind}" + (f" d={d:g}" if d else "")
        if why is not None:
            rows.append((name, "cold", None, None, None, f"rejected: {why.limit}"))
            continue
        session_kind = session_kind or (kind if kind != "hop" else None)
        rows.append((name, "cold", statistics.median(times), max(times), statistics.median(its), ""))
    if session_kind:
        s = P.FlipSession(session_kind, apex_height=apex, platform_height=a.platform, **robot_kw)
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
        rows.append((f"landing {session_kind} (perturbed)", "warm", statistics.median(times), max(times),
                     statistics.median(its), ""))
    print(f"flywheel {a.flywheel}, motor speed scale {a.motor_speed_scale:g}, flywheel torque "
          f"{a.flywheel_torque or 'own'}, apex {apex:.2f} m, platform {a.platform:g} m; robot model "
          f"{t_robot:.2f} s, jumping NLP build {t_build:.2f} s (the first solve also sets up IPOPT: see max)")
    print(f"{'problem':34s} {'start':5s} {'median ms':>10s} {'max ms':>8s} {'iters':>6s}")
    for name, kind, med, mx, it, note in rows:
        if med is None:
            print(f"{name:34s} {kind:5s} {note}")
        else:
            print(f"{name:34s} {kind:5s} {1e3 * med:10.1f} {1e3 * mx:8.1f} {it:6.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
