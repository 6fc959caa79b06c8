"""flip run: a flip (or a hop: a jump without rotation) through every node of the graph, recorded,
then summarised and plotted from the bag; exit 0 when the bag shows the robot landed."""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from flip_tools.flip_request import request_distance

from .common import (EXIT_INFRA, EXIT_INTERRUPTED, EXIT_NOT_LANDED, EXIT_OK, EXIT_REJECTED, KINDS, NONNEGATIVE,
                     POSITIVE, log, prepare_out)
from .graph import Graph, run_graph
from .options import controller_opt, graph_opts, scenario_opts
from .params import (SIM_MIN_SUBSCRIBERS, check_live_port, landing_ground_z, plant_params, robot_params,
                     scenario_params, sim_loop_params, takeoff_ground_z, tsc_params, wrench_params)
from .progress import JUMP_ALLOWANCE_S, landing_end, wait_for_sim_end, wait_sim_time
from .results import finish, print_summary
from .services import call_request_flip, call_trigger, response_dict

#: the nodes of a flip's graph (the recorder is stopped after them)
ROLES = ["state", "tsc", "planner", "sim"]


def add_parser(sub) -> None:
    sp = sub.add_parser("run", help="a flip (or a hop: a jump without rotation) with every node + recorder, "
                                    "summary and plots")
    sp.add_argument("kind", choices=["backflip", "frontflip", "hop"])
    scenario_opts(sp)
    sp.add_argument("--out", help="output dir (default runs/<kind>-<time>)")
    sp.add_argument("--plant", nargs="+", metavar="KNOB=V",
                    help="the simulated robot perturbed, unknown to the planner and controller (as `flip sweep` "
                         "does): friction, mass_scale, com_offset, torque_scale, delay_steps, push, push_phase "
                         "(`flip sweep --help` says what each does)")
    sp.add_argument("--no-plots", action="store_true", help="summary.json only, no plots (as `flip sweep` runs it)")
    sp.add_argument("--video", action="store_true",
                    help="render DIR/flip.mp4 (DIR/flip.gif without ffmpeg) from the bag after the run")
    sp.add_argument("--duration", type=POSITIVE, help="sim duration, s (default: until --settle s after the touch-down)")
    sp.add_argument("--request-at", type=NONNEGATIVE, default=0.5,
                    help="sim time to request the flip at, s: the robot has settled on its feet by then "
                         "(the planner refuses a robot that is not standing at rest)")
    sp.add_argument("--settle", type=NONNEGATIVE, default=5.0, help="sim seconds after the touch-down, s")
    sp.add_argument("--max-sim-time", type=POSITIVE, default=60.0, help="sim duration cap passed at launch, s")
    sp.add_argument("--request-timeout", type=POSITIVE, default=300.0)
    controller_opt(sp)
    graph_opts(sp)
    sp.set_defaults(func=cmd_run)


def run_setup(args) -> dict:
    """run.json's start: every node's parameters and the request, each argument checked (SystemExit)."""
    kind = args.kind
    if args.request_at >= (args.duration or args.max_sim_time):
        raise SystemExit(f"--request-at {args.request_at:g} s is not before the run's end "
                         f"({args.duration or args.max_sim_time:g} s of sim time)")
    scen = scenario_params(args)
    ground_z = landing_ground_z(args)
    distance = request_distance(args)
    if args.distance is None and distance:
        where = "beyond the platform" if (args.platform or 0.0) > 0.0 else "on the raised landing area"
        log(f"forward distance {distance} m, to land {where} (--distance to choose)")
    # min_subscribers: the sim holds its first step until the recorder and the state publisher are
    # subscribed too
    # linger: at its end the sim keeps its publishers until stopped, which the tool does once the
    # recorder has all they sent
    # hold: and before its first step until flip releases it, once the recorder reports its side matched
    sim_params = {"mode": "lockstep", "controller": "tsc", "min_subscribers": SIM_MIN_SUBSCRIBERS, "linger": True,
                  "hold": True,
                  "duration": float(args.duration if args.duration else args.max_sim_time),
                  **robot_params(args), **scen, **plant_params(args), **sim_loop_params(args), **wrench_params(args)}
    planner_params = {**robot_params(args), "platform_height": float(args.platform or 0.0),
                      "flight_check": not args.no_flight_check, "knee_tangential": bool(args.knee_tangential)}
    return {"command": sys.argv, "kind": kind, "robot": args.robot, "sim_params": sim_params,
            "planner_params": planner_params,
            "tsc_params": tsc_params(args),
            "request": {"kind": kind, "apex_height": args.apex or 0.0, "forward_distance": distance,
                        "platform_height": args.platform or 0.0},
            "landing_ground_z": ground_z, "takeoff_ground_z": takeoff_ground_z(args)}


def start_flip_graph(graph: Graph, args, run_info: dict) -> float:
    """Recorder, live view, state publisher, simulator, planner and controller started, up to the
    recorder matched on every per-step topic; the wall seconds that took."""
    graph.start_recorder()
    graph.start_live(args, run_info)
    graph.start_state_publisher(args)
    graph.start_node("sim", args, run_info["sim_params"])
    graph.start_node("planner", args, run_info["planner_params"])
    graph.start_node("tsc", args, tsc_params(args))
    graph.follow_clock()
    took = graph.watcher.wait_ready(
        nodes=["sim_node", "planner_node", "tsc_node", "state_publisher", "flip_recorder"],
        services=["/request_flip"],
        topics={"/joint_states": (1, 2), "/motor_command": (1, 2), "/odom": (1, 1), "/clock": (1, 1),
                "/robot_description_mjcf": (1, 1)},
        timeout=args.ready_timeout, launcher=graph.launcher)
    # the foot wrenches too: the simulator is released (steps from 0) once the recorder has them all
    took += graph.wait_recorder_matched(["/clock", "/odom", "/joint_states", "/motor_command",
                                         "/robot_description_mjcf"] + graph.foot_wrench_topics(),
                                        args.ready_timeout)
    call_trigger(graph.watcher, "/sim/release", args.ready_timeout)
    graph.release_live()
    return took


def fly(graph: Graph, args, run_info: dict, extra: dict) -> int:
    """The flip in a graph: started, the request at --request-at, then running to its end (--duration,
    or --settle s after the touch-down)."""
    kind, req = args.kind, run_info["request"]
    took = start_flip_graph(graph, args, run_info)
    run_info["graph_ready_s"] = round(took, 3)
    log(f"graph ready in {took:.2f} s (recorder matched); requesting {kind} at sim t >= {args.request_at:g} s")
    run_info["request_sim_time"] = round(wait_sim_time(graph, args.request_at, args.ready_timeout), 4)
    resp = call_request_flip(graph.watcher, KINDS[kind], req["apex_height"], req["forward_distance"],
                             req["platform_height"], timeout=args.request_timeout)
    extra["response"] = response_dict(resp)
    print(json.dumps({"response": extra["response"]}))
    if not resp.accepted:
        print(f"request rejected: {resp.reason}")
        extra["outcome"] = "rejected"
        return EXIT_REJECTED
    for _ in range(50):
        if graph.sim_now() is not None:
            break
        graph.spin(0.05)
    now = graph.sim_now() or 0.0
    if args.duration:
        end_sim = float(args.duration)
        log(f"accepted (plan {resp.plan_id}, flight {resp.flight_time:.3f} s); "
            f"running to sim t = {end_sim:.2f} s")
    else:
        # the tool stops the sim (wait_for_sim_end) --settle s after the first touch-down (or
        # body contact) from now; until one comes, after a bound on the jump's stance and
        # flight; the sim's own duration, given at launch, is only the cap
        end_sim = landing_end(graph, now, now + JUMP_ALLOWANCE_S + resp.flight_time + args.settle,
                              args.settle, run_info)
        log(f"accepted (plan {resp.plan_id}, flight {resp.flight_time:.3f} s); running until "
            f"{args.settle:g} s of sim time after the touch-down")
    rc = wait_for_sim_end(graph, end_sim, args.timeout, ROLES)
    if callable(end_sim):
        end_sim = end_sim()
    run_info["end_sim_time"] = round(end_sim, 4)
    # the newest sim time the tool read when it stopped waiting (the bag may lack the last steps)
    run_info["stop_sim_time"] = None if graph.sim_time is None else round(float(graph.sim_time), 4)
    return rc


def cmd_run(args) -> int:
    out = Path(args.out or f"runs/{args.kind}-{time.strftime('%Y%m%d-%H%M%S')}")
    run_info = run_setup(args)
    check_live_port(args)
    prepare_out(out)        # after every argument has been checked
    extra = {"run": run_info}
    # the simulator stops first: stopped after its controller, a lockstep simulator re-sends its
    # last state every 50 ms until its own stop comes (copies in the bag, not stepping time)
    rc, graph, report = run_graph(args, out, "lockstep", run_info, extra, ["sim"] + [r for r in ROLES if r != "sim"],
                                  lambda graph: fly(graph, args, run_info, extra))
    (out / "run.json").write_text(json.dumps(run_info, indent=2))
    summary = finish(out, graph, report, extra, args.kind, run_info["landing_ground_z"],
                     run_info["takeoff_ground_z"], plots=not args.no_plots)
    if args.video and (out / "bag" / "metadata.yaml").exists():
        try:
            video = render_video(out, args)
            log(f"video: {video}")
        except Exception as e:  # noqa: BLE001 - a video is extra: the run's result stands without it
            log(f"no video: {e}")
    print(f"{out}: outcome {summary.get('outcome')}")
    print_summary(summary)
    return run_exit(rc, extra, report, summary)


def run_exit(rc: int, extra: dict, report: dict, summary: dict) -> int:
    """The run's exit code: the graph's (rejected, interrupted, an error), 3 when a node exited with an
    error by itself, else the bag's verdict (0 landed, 1 not)."""
    crashed = {n: r["returncode"] for n, r in report.items()
               if r.get("stopped_by") == "exited" and r.get("returncode") != 0 and n != "live"}
    if crashed:
        log(f"a node exited with an error by itself: {crashed}")
    if rc in (EXIT_REJECTED, EXIT_INTERRUPTED) or "error" in extra:
        return rc
    if crashed:
        return EXIT_INFRA
    return EXIT_OK if summary.get("outcome") == "landed" else EXIT_NOT_LANDED


def render_video(out: Path, args) -> Path:
    """DIR/flip.mp4 (or .gif without ffmpeg) rendered from the run's bag, terrain as simulated."""
    from cassie_flip_sim.perturbation import with_landing_offset
    from cassie_model.model import Scenario
    from flip_tools.video import render_run
    sp = scenario_params(args)
    scen = {"flat": Scenario.flat,
            "platform": lambda: with_landing_offset(Scenario.platform(sp.get("platform_height", 0.5)),
                                                    sp.get("landing_height", 0.0)),
            "raised": lambda: Scenario.raised_landing(sp.get("ground_offset", 0.1))}[sp["scenario"]]()
    return render_run(out, getattr(args, "flywheel", None) or "I", scen)
