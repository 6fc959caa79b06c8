#!/usr/bin/env python3
"""Planner verdicts over a grid of requests under several OpenBLAS kernels.

Plans every request of the grid kind ∈ {backflip, frontflip} × apex 1.00–1.40 m (0.05 steps) ×
distance ∈ {0, 0.5, 1.0} × platform ∈ {0, 0.5} (each a cold solve, no ROS) once per kernel, each
kernel in its own process (``OPENBLAS_CORETYPE`` is read when the library loads), and prints per
kernel: accepted / rejected counts, the limits named by the rejections, iterations and solve time
(median / max) of the accepted requests, then the requests whose verdict differs between kernels.

    .venv/bin/python scripts/bench_planner_grid.py [--kernels default,Haswell,Prescott]
        [--flywheel I] [--motor-speed-scale X] [--flywheel-torque NM] [--json OUT]
        [--apexes 1.0,1.1 --distances 0,0.6 --platforms 0,0.5] [--each]

``--apexes``, ``--distances``, ``--platforms`` replace the grid's values; ``--each`` also prints every
request's verdict under the first kernel (the limit and the reason's figures).

``default`` runs with ``OPENBLAS_CORETYPE`` and ``OPENBLAS_L2_SIZE`` unset (the kernel OpenBLAS
picks for this CPU).
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import time
from collections import Counter

KINDS = ("backflip", "frontflip")
#: the figures a refusal's reason gives: torque needed, sink against the landable one, reachable apex
FIGURE = re.compile(r"needs ≥[0-9]+ N·m|COM sink [0-9.]+ m/s|at most ≈[0-9.]+ m/s of sink|max reachable apex ≈ [0-9.]+ m")
APEXES = tuple(round(1.00 + 0.05 * i, 2) for i in range(9))
DISTANCES = (0.0, 0.5, 1.0)
PLATFORMS = (0.0, 0.5)


def grid(apexes=APEXES, distances=DISTANCES, platforms=PLATFORMS):
    return [(k, a, d, p) for k in KINDS for a in apexes for d in distances for p in platforms]


def floats(text):
    return tuple(float(v) for v in text.split(","))


def run_grid(flywheel, motor_speed_scale, flywheel_torque, requests):
    """Plan every request in this process; one JSON record per request."""
    from fslip_planner import plan as P
    out = []
    for kind, apex, dist, plat in requests:
        t0 = time.perf_counter()
        rec = dict(kind=kind, apex=apex, distance=dist, platform=plat)
        try:
            r = P.plan_flip(kind, apex_height=apex, forward_distance=dist, platform_height=plat,
                            flywheel=flywheel, motor_speed_scale=motor_speed_scale,
                            flywheel_torque=flywheel_torque)
            rec.update(verdict="accepted", iterations=r.figures["iterations"],
                       solve_time=r.figures["solve_time"], attempt=r.figures.get("attempt", 0),
                       lift_off={k: r.lift_off[k] for k in ("zdot", "xdot", "beta", "momentum")},
                       flight_torque_needed=r.figures["flight_torque_needed"])
        except P.InfeasibleRequest as e:
            rec.update(verdict="rejected", reason=str(e), limit=getattr(e, "limit", "?"))
        rec["wall"] = time.perf_counter() - t0
        out.append(rec)
    return out


def kernel_env(kernel):
    env = dict(os.environ)
    env.pop("OPENBLAS_CORETYPE", None)
    env.pop("OPENBLAS_L2_SIZE", None)
    if kernel != "default":
        env["OPENBLAS_CORETYPE"] = kernel
        if kernel == "Haswell":
            env["OPENBLAS_L2_SIZE"] = "512"
    return env


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--kernels", default="default,Haswell,Prescott")
    ap.add_argument("--flywheel", default="I")
    ap.add_argument("--motor-speed-scale", type=float, default=1.0)
    ap.add_argument("--flywheel-torque", type=float, default=None)
    ap.add_argument("--json", help="write every record here")
    ap.add_argument("--apexes", type=floats, default=APEXES)
    ap.add_argument("--distances", type=floats, default=DISTANCES)
    ap.add_argument("--platforms", type=floats, default=PLATFORMS)
    ap.add_argument("--each", action="store_true", help="every request's verdict under the first kernel")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    requests = grid(a.apexes, a.distances, a.platforms)
    if a.worker:
        json.dump(run_grid(a.flywheel, a.motor_speed_scale, a.flywheel_torque, requests), sys.stdout)
        return 0
    results = {}
    for kernel in a.kernels.split(","):
        cmd = [sys.executable, os.path.abspath(__file__), "--worker", "--flywheel", a.flywheel,
               "--motor-speed-scale", str(a.motor_speed_scale)]
        for name in ("apexes", "distances", "platforms"):
            cmd += [f"--{name}", ",".join(str(v) for v in getattr(a, name))]
        if a.flywheel_torque:
            cmd += ["--flywheel-torque", str(a.flywheel_torque)]
        p = subprocess.run(cmd, env=kernel_env(kernel), capture_output=True, text=True)
        if p.returncode != 0:
            print(f"kernel {kernel}: the worker failed (exit {p.returncode}):\n{p.stderr[-2000:]}", file=sys.stderr)
            return 3
        results[kernel] = json.loads(p.stdout)
    print(f"grid: {len(requests)} requests (kinds {', '.join(KINDS)}; apex {a.apexes[0]:.2f}-{a.apexes[-1]:.2f} m; "
          f"distance {a.distances}; platform {a.platforms}); flywheel {a.flywheel}, motor speed scale "
          f"{a.motor_speed_scale:g}, flywheel torque {a.flywheel_torque or 'own'}")
    print(f"{'kernel':10s} {'accepted':>8s} {'rejected':>8s} {'iters med/max':>14s} {'solve s med/max':>16s} "
          f"{'2nd start':>9s}  rejections by limit")
    for kernel, recs in results.items():
        acc = [r for r in recs if r["verdict"] == "accepted"]
        rej = [r for r in recs if r["verdict"] == "rejected"]
        its = [r["iterations"] for r in acc] or [0]
        ts = [r["solve_time"] for r in acc] or [0.0]
        lim = Counter(r["limit"] for r in rej)
        print(f"{kernel:10s} {len(acc):8d} {len(rej):8d} {statistics.median(its):7.0f}/{max(its):<6d} "
              f"{statistics.median(ts):8.3f}/{max(ts):<7.3f} {sum(1 for r in acc if r['attempt']):9d}  "
              + ", ".join(f"{k}: {v}" for k, v in sorted(lim.items())))
    kernels = list(results)
    differ = []
    for i, req in enumerate(requests):
        verdicts = {k: results[k][i]["verdict"] for k in kernels}
        if len(set(verdicts.values())) > 1:
            differ.append((req, verdicts))
    print(f"verdicts that differ between kernels: {len(differ)}")
    for req, v in differ:
        print(f"  {req}: " + ", ".join(f"{k} {x}" for k, x in v.items()))
    if a.each:
        print(f"every request under kernel {kernels[0]}: kind, apex, distance, platform, verdict")
        for req, r in zip(requests, results[kernels[0]]):
            why = (f"{r['limit']}: " + "; ".join(FIGURE.findall(r["reason"])) if r["verdict"] == "rejected"
                   else f"flight {r['lift_off']['zdot']:.2f} m/s lift-off")
            print(f"  {req[0]:9s} {req[1]:.2f} {req[2]:.2f} {req[3]:.2f}  {r['verdict']:8s} {why}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(results, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
