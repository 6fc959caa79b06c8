"""Option groups several subcommands share: the jump asked for, the robot, the controller, the graph."""
from __future__ import annotations

from flip_tools.flip_request import PLATFORM_FLIP_DISTANCE

from .common import FINITE, NONNEGATIVE, POSITIVE, cpu_latency_arg


def scenario_opts(sp, plan=False, flight_check=True, robot=True):
    """The jump's request (distance, apex, platform; the landing ground's offset but in ``plan``'s
    subcommands), the robot (``robot``: the subcommands that build one) and (``flight_check``: the
    subcommands that start a planner) --no-flight-check."""
    sp.add_argument("--distance", type=FINITE,
                    help=f"forward distance, m (default 0 = in place; {PLATFORM_FLIP_DISTANCE} with --platform)")
    sp.add_argument("--apex", type=NONNEGATIVE, help="COM apex above take-off ground, m (0 = default)")
    sp.add_argument("--platform", type=NONNEGATIVE, help="take-off platform height above the landing ground, m")
    if not plan:
        sp.add_argument("--ground-offset", type=FINITE, help="landing ground offset (scenario raised), m")
    if robot:
        robot_opts(sp)
    if flight_check:
        flight_check_opt(sp)
        knee_model_opt(sp)


def robot_opts(sp):
    """--robot and the flags that change one of its parameters."""
    from cassie_model.robot_params import DEFAULT_ROBOT, ROBOTS
    sp.add_argument("--robot", choices=list(ROBOTS), default=DEFAULT_ROBOT,
                    help=f"named robot (default {DEFAULT_ROBOT}: " + ROBOTS[DEFAULT_ROBOT].about
                         + "); the flags below change one of its parameters")
    sp.add_argument("--flywheel", choices=["I", "II", "III"], help="Table I flywheel (default: the robot's)")
    sp.add_argument("--motor-speed-scale", type=POSITIVE,
                    help="leg motors' no-load speeds x this (default: the robot's; 1 = the published motors)")
    sp.add_argument("--flywheel-torque", type=POSITIVE, metavar="NM",
                    help="flywheel motor's torque limit, N*m (default: the robot's, 195)")


def flight_check_opt(sp):
    """--no-flight-check: the planner's flight-torque check off (a design study)."""
    sp.add_argument("--no-flight-check", action="store_true",
                    help="design study: the planner does not refuse a jump whose planned flight needs more "
                         "flywheel torque than the motor gives (the robot may fly longer than its plan); "
                         "the torque it needs is still reported")


def knee_model_opt(sp):
    """--knee-tangential: the planner's knee torque counts the tangential foot force too."""
    sp.add_argument("--knee-tangential", action="store_true",
                    help="plan with the knee torque of the tangential foot force too, (F^s + rho(L) f_t) "
                         "dL/dq_knee, not of the leg's axial force alone (FSLIPParams.knee_tangential)")


def controller_opt(sp):
    """--controller: ControllerConfig overrides as JSON."""
    sp.add_argument("--controller", metavar="JSON",
                    help="controller settings (tsc_controller ControllerConfig fields), e.g. "
                         "'{\"cop_margin_domains\": {\"JUMPING\": 0.2}}'")


def graph_opts(sp):
    """What a subcommand that starts a graph takes: domain, node overrides, timeouts, CPU latency and
    scheduling, the live view, the simulator's loop and wrench rate."""
    from flip_tools.live import add_live_options
    sp.add_argument("--domain", type=int, help="ROS_DOMAIN_ID (default: a free one, 1..100)")
    sp.add_argument("--exe", action="append", metavar="ROLE=CMD",
                    help="override a node command (roles: sim, planner, tsc, state, live), e.g. for stand-in nodes")
    sp.add_argument("--timeout", type=POSITIVE, default=1800.0, help="wall-clock limit of the run, s")
    sp.add_argument("--ready-timeout", type=POSITIVE, default=120.0, help="graph discovery limit, s")
    sp.add_argument("--cpu-dma-latency", type=cpu_latency_arg, default=0, metavar="US|off",
                    help="hold /dev/cpu_dma_latency at US microseconds while the graph runs (default 0: "
                         "idle CPUs poll, waking the recorder's CPU is cheap; needs write access, "
                         "without it the run goes ahead and run.json says so); off: leave it alone")
    sp.add_argument("--lockstep-sched", choices=["batch", "other"],
                    help="scheduling policy of the simulator and controller on their shared CPU "
                         "(default batch in lockstep: a woken thread does not preempt the running one; "
                         "other, the kernel's default, in realtime mode)")
    add_live_options(sp)
    sp.add_argument("--sim-loop", default="compiled", choices=["compiled", "python"],
                    help="the simulator's lockstep loop: its routine steps in C++ (default; with the "
                         "controller and rcl's C API) or every step in Python (the same messages)")
    sp.add_argument("--wrench-rate", type=NONNEGATIVE, metavar="HZ",
                    help="rate of the feet's contact wrenches (/left_foot/wrench, /right_foot/wrench), "
                         "Hz of sim time (default 200: every 10th step; 0: none)")
