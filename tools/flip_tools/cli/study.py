"""flip study flywheel: the paper's Table I, flip C (frontflip from a 0.5 m platform) planned for
flywheels I, II, III, and with --simulate run through the node graph too."""
from __future__ import annotations

import json
import math
import subprocess
import time
from pathlib import Path

from flip_tools.flip_request import PLATFORM_FLIP_DISTANCE, request_distance

from .common import EXIT_OK, EXIT_REJECTED, FLIP_CMD
from .options import robot_opts
from .params import robot_params

#: paper, Table I: flywheel -> (I_pitch kg m^2, mass kg, peak speed its flip C needed, rpm)
PAPER_TABLE_I = {"I": (0.1074, 9.54, 1645.0), "II": (0.2148, 19.09, 812.0), "III": (0.3222, 28.63, 573.0)}


def add_parser(sub) -> None:
    sp = sub.add_parser("study", help="Table I study: flip C with flywheels I, II, III")
    sp.add_argument("what", choices=["flywheel"])
    sp.add_argument("--platform", type=float, default=0.5)
    sp.add_argument("--apex", type=float, default=1.2, help="COM apex above the platform, m")
    sp.add_argument("--distance", type=float,
                    help=f"forward distance, m (default {PLATFORM_FLIP_DISTANCE}: beyond the platform's edge)")
    robot_opts(sp)
    sp.add_argument("--simulate", action="store_true", help="also run each flip through the node graph")
    sp.add_argument("--out", help="output dir (default runs/study-flywheel-<time>)")
    sp.set_defaults(func=cmd_study)


def plan_row(args, fw: str, robot: dict, distance: float) -> dict:
    """One flywheel's row: Table I's figures and the FSLIP plan's peak flywheel speed (None and the
    reason when the plan is infeasible)."""
    from fslip_planner import plan as planmod
    I_p, mass, paper_rpm = PAPER_TABLE_I[fw]
    row = {"flywheel": fw, "I_pitch": I_p, "mass": mass, "paper_rpm": paper_rpm}
    try:
        r = planmod.plan_flip("frontflip", apex_height=args.apex, platform_height=args.platform,
                              forward_distance=distance,
                              flywheel=fw, motor_speed_scale=robot["motor_speed_scale"],
                              flywheel_torque=robot["flywheel_torque"])
        f = r.to_dict()
        row.update(planned_rpm=f["peak_flywheel_speed"] * 60 / (2 * math.pi),
                   liftoff_zdot=f["liftoff_zdot"], flight_time=f["flight_time"],
                   liftoff_momentum=f["lift_off"]["momentum"])
    except planmod.InfeasibleRequest as e:
        row.update(planned_rpm=None, reason=str(e))
    return row


def simulate_row(args, row: dict, robot: dict, distance: float, out: Path) -> None:
    """--simulate: the row's flip as `flip run` into DIR/flip_C_<flywheel>; its exit code, outcome and
    measured peak flywheel speed (summary.json) into the row."""
    fw = row["flywheel"]
    run_dir = out / f"flip_C_{fw}"
    cmd = [*FLIP_CMD, "run", "frontflip", "--platform", str(args.platform),
           "--apex", str(args.apex), "--distance", str(distance), "--robot", args.robot, "--flywheel", fw,
           "--motor-speed-scale", str(robot["motor_speed_scale"]), "--flywheel-torque", str(robot["flywheel_torque"]),
           "--out", str(run_dir)]
    rc = subprocess.run(cmd).returncode
    try:
        summ = json.loads((run_dir / "summary.json").read_text())
    except (OSError, ValueError):
        summ = {}
    row.update(run_exit=rc, outcome=summ.get("outcome"), measured_rpm=summ.get("peak_flywheel_rpm"))


def print_study(args, rows: list[dict], robot: dict, distance: float) -> None:
    print(f"flip C (frontflip, platform {args.platform} m, apex {args.apex} m, distance {distance} m), "
          f"flywheel limit {robot['flywheel_torque']:g} N*m, "
          f"robot {args.robot}, leg motor speed x{robot['motor_speed_scale']}")
    hdr = f"{'flywheel':>8} {'I (kg m2)':>9} {'m (kg)':>6} {'paper rpm':>9} {'planned rpm':>11}"
    if args.simulate:
        hdr += f" {'measured rpm':>12} {'outcome':>10}"
    print(hdr)
    for r in rows:
        pr = f"{r['planned_rpm']:.0f}" if r.get("planned_rpm") is not None else "infeasible"
        line = f"{r['flywheel']:>8} {r['I_pitch']:>9.4f} {r['mass']:>6.2f} {r['paper_rpm']:>9.0f} {pr:>11}"
        if args.simulate:
            mr = r.get("measured_rpm")                  # none where the plan was refused or the run left none
            line += f" {'-' if mr is None else str(round(mr)):>12} {r.get('outcome') or '-':>10}"
        print(line)
        if r.get("reason"):
            print(f"{'':>10}{r['reason']}")


def cmd_study(args) -> int:
    """Table I study: flip C (frontflip from a 0.5 m platform, apex 1.2 m above it) for flywheels
    I, II, III with the 195 N*m flywheel limit (or --flywheel-torque).  The planned peak flywheel
    speed comes from the FSLIP jumping plan (no ROS); with --simulate each flip is also run through
    the node graph and the measured peak speed read from its bag (summary.json)."""
    robot = robot_params(args)
    distance = request_distance(args)
    out = Path(args.out or f"runs/study-flywheel-{time.strftime('%Y%m%d-%H%M%S')}")
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for fw in PAPER_TABLE_I:
        row = plan_row(args, fw, robot, distance)
        if args.simulate and row.get("planned_rpm") is not None:
            simulate_row(args, row, robot, distance, out)
        rows.append(row)
    (out / "study.json").write_text(json.dumps({"platform": args.platform, "apex": args.apex, "distance": distance,
                                                "robot": args.robot, "motor_speed_scale": robot["motor_speed_scale"],
                                                "flywheel_torque": robot["flywheel_torque"], "rows": rows},
                                               indent=2))
    print_study(args, rows, robot, distance)
    print(f"{out / 'study.json'} written")
    return EXIT_OK if all(r.get("planned_rpm") is not None for r in rows) else EXIT_REJECTED
