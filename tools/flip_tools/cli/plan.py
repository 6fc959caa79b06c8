"""flip plan: the FSLIP jumping optimisation alone, no ROS -> DIR/plan.json (exit 4: infeasible)."""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from flip_tools.flip_request import request_distance

from .common import EXIT_INFRA, EXIT_OK, EXIT_REJECTED, KINDS, json_default
from .options import scenario_opts
from .params import robot_params


def add_parser(sub) -> None:
    sp = sub.add_parser("plan", help="FSLIP jumping optimisation alone (no ROS) -> DIR/plan.json")
    sp.add_argument("kind", choices=list(KINDS))
    scenario_opts(sp, plan=True)
    sp.add_argument("--out", required=True)
    sp.set_defaults(func=cmd_plan)


def cmd_plan(args) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    try:
        from fslip_planner import plan as planmod
    except ImportError as e:
        print(f"the FSLIP planner is not available: {e}", file=sys.stderr)
        return EXIT_INFRA
    kw = {"apex_height": float(args.apex or 0.0), "forward_distance": request_distance(args),
          "platform_height": float(args.platform or 0.0)}
    kw.update(robot_params(args))
    if args.no_flight_check:
        kw["flight_check"] = False
    if args.knee_tangential:
        kw["knee_tangential"] = True
    t0 = time.perf_counter()
    try:
        result = planmod.plan_flip(args.kind, **kw)
    except planmod.InfeasibleRequest as e:
        print(f"infeasible: {e}", file=sys.stderr)
        (out / "plan.json").write_text(json.dumps({"kind": args.kind, "request": kw, "feasible": False,
                                                   "reason": str(e)}, indent=2))
        return EXIT_REJECTED
    wall = time.perf_counter() - t0
    d = result.to_dict() if hasattr(result, "to_dict") else dict(result)
    doc = {"kind": args.kind, "request": kw, "feasible": True, "wall_time_s": wall, "plan": d}
    (out / "plan.json").write_text(json.dumps(doc, indent=2, default=json_default))
    print(f"{out / 'plan.json'} written ({wall:.2f} s)")
    for k in ("liftoff_zdot", "liftoff_xdot", "flight_time", "peak_flywheel_speed", "solve_time", "iterations"):
        if isinstance(d, dict) and k in d:
            print(f"  {k}: {d[k]}")
    return EXIT_OK
