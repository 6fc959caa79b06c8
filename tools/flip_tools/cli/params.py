"""The nodes' commands and ROS parameters, made from the command line's arguments and checked
before anything starts (a refused value is a SystemExit: exit 2)."""
from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

from .common import FLIP_CMD

NODE_EXES = {"sim": "sim_node", "planner": "planner_node", "tsc": "tsc_node", "state": "state_publisher"}

#: sim_node's min_subscribers under `flip`: the recorder and the state publisher read /joint_states
#: and /odom (+ the controller, which sim_node counts itself); /clock's two are the recorder and
#: this tool (follow_clock)
SIM_MIN_SUBSCRIBERS = 2


def node_cmd(role: str, args) -> list[str]:
    """Command of a node: the console script in the venv, or an override
    (--exe ROLE=CMD, or env FLIP_SIM_CMD / FLIP_PLANNER_CMD / FLIP_TSC_CMD / FLIP_STATE_CMD; CMD split
    on spaces)."""
    overrides = dict(e.split("=", 1) for e in (getattr(args, "exe", None) or []))
    cmd = overrides.get(role) or os.environ.get(f"FLIP_{role.upper()}_CMD")
    if cmd:
        return cmd.split()
    exe = Path(sys.prefix) / "bin" / NODE_EXES[role]
    return [str(exe if exe.exists() else NODE_EXES[role])]


def recorder_cmd(bag_dir: Path, stats: Path) -> list[str]:
    from flip_tools.rosenv import CONTRACT_TOPICS
    # the contract topics are subscribed at once (types/QoS known), any other topic when it appears
    return [*FLIP_CMD, "record", *CONTRACT_TOPICS, "--all", "--bag", str(bag_dir), "--stats", str(stats)]


def robot_params(args) -> dict:
    """The robot's design parameters, given alike to every node that models the robot: those of
    ``--robot`` (default: the paper's robot), each replaced by its own flag where one is given."""
    from cassie_model.robot_params import DEFAULT_ROBOT, robot
    p = robot(getattr(args, "robot", None) or DEFAULT_ROBOT).params()
    if getattr(args, "flywheel", None):
        p["flywheel"] = args.flywheel
    if getattr(args, "motor_speed_scale", None) is not None:
        if not args.motor_speed_scale > 0:
            raise SystemExit("--motor-speed-scale must be > 0")
        p["motor_speed_scale"] = float(args.motor_speed_scale)
    if getattr(args, "flywheel_torque", None) is not None:
        if not (math.isfinite(args.flywheel_torque) and args.flywheel_torque > 0):
            raise SystemExit("--flywheel-torque must be a finite number > 0 (N*m)")
        p["flywheel_torque"] = float(args.flywheel_torque)
    return p


def sim_loop_params(args) -> dict:
    """sim_node's compiled_loop: its routine lockstep steps in C++ (default) or, with --sim-loop
    python, every step in Python (the same messages; to compare the two)."""
    return {"compiled_loop": False} if getattr(args, "sim_loop", "compiled") == "python" else {}


def wrench_params(args) -> dict:
    """sim_node's wrench_rate (Hz of sim time; 0: no /left_foot/wrench, /right_foot/wrench) when
    --wrench-rate is given; else the node's default (200 Hz)."""
    rate = getattr(args, "wrench_rate", None)
    return {} if rate is None else {"wrench_rate": float(rate)}


def tsc_params(args) -> dict:
    """tsc_node's parameters: the robot's (but the flywheel, which it reads from /robot_description_mjcf)
    and ``--controller`` (ControllerConfig fields as JSON), checked here before anything starts."""
    # min_subscribers (lockstep): the recorder's /motor_command matched before the first command (on
    # the wall clock the simulator would step on without commands meanwhile)
    p = {k: v for k, v in robot_params(args).items() if k != "flywheel"}
    if getattr(args, "mode", "lockstep") == "lockstep":
        p["min_subscribers"] = 1
    else:                   # realtime: the simulator steps on without the planner's reference, so does the node
        p["hold_for_reference"] = False
    text = getattr(args, "controller", None)
    if text:
        from tsc_controller.config import config_overrides
        try:
            config_overrides(text)
        except ValueError as e:
            raise SystemExit(f"--controller: {e}")
        p["controller"] = text
    if getattr(args, "io", "rcl") != "rcl":
        p["rcl_io"] = False
    return p


def scenario_params(args) -> dict:
    """sim_node's terrain: flat, a take-off platform (--platform M), a raised (or lowered) landing
    area (--ground-offset M), or both (the landing area's height: sim_node's ``landing_height``)."""
    p = {}
    platform = getattr(args, "platform", None) or 0.0
    offset = getattr(args, "ground_offset", None) or 0.0
    if platform:
        p.update(scenario="platform", platform_height=float(platform))
        if offset:
            p["landing_height"] = float(offset)
    elif offset:
        p.update(scenario="raised", ground_offset=float(offset))
    else:
        p.update(scenario="flat")
    return p


def plant_params(args) -> dict:
    """sim_node's ``plant`` (--plant KNOB=V ...: the robot perturbed as the planner and controller
    are not told; cassie_flip_sim.perturbation), checked here (exit 2), or nothing."""
    items = getattr(args, "plant", None)
    if not items:
        return {}
    from cassie_flip_sim.perturbation import PLANT_KNOBS, check_knob
    knobs = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or name not in PLANT_KNOBS or name in knobs:
            raise SystemExit(f"--plant: expected KNOB=VALUE with one of {', '.join(PLANT_KNOBS)} once each, "
                             f"got {item!r}")
        try:
            knobs[name] = check_knob(name, value)
        except ValueError as e:
            raise SystemExit(f"--plant: {e}") from None
    return {"plant": json.dumps(knobs, sort_keys=True)}


def landing_ground_z(args) -> float:
    """Height of the landing ground in the world frame, from the scenario (cassie_flip_sim
    Scenario): ground at z = 0; --platform M = take off from a platform of top z = M and land on
    the ground; --ground-offset M = the landing area ahead is raised to z = M (flip D; whether the
    feet came down on it is the summary's ``touchdown_on_landing_ground`` check)."""
    return float(getattr(args, "ground_offset", None) or 0.0)


def takeoff_ground_z(args) -> float:
    return float(getattr(args, "platform", None) or 0.0)


def check_live_port(args) -> None:
    """--live: a --live-port that cannot be listened on (already in use) is refused before anything
    starts (exit 2); 0 picks a free one."""
    from flip_tools.live import port_problem
    problem = getattr(args, "live", False) and port_problem(args.live_port)
    if problem:
        raise SystemExit(f"--live-port {args.live_port}: {problem}; choose another, or 0 for a free one")


def lockstep_sched(args, mode: str) -> str:
    """--lockstep-sched, or its default for the simulator's mode: batch in lockstep, the kernel's
    default (other) on the wall clock."""
    return args.lockstep_sched or ("batch" if mode == "lockstep" else "other")
