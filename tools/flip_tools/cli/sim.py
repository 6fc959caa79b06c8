"""flip sim: the simulator alone (zero torques), recorded; and what flip stand shares with it (the
same graph with the controller holding the standing pose)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from .common import EXIT_NOT_LANDED, EXIT_OK, FINITE, NONNEGATIVE, POSITIVE, log, prepare_out
from .graph import Graph, run_graph
from .options import controller_opt, graph_opts, robot_opts
from .params import (SIM_MIN_SUBSCRIBERS, check_live_port, landing_ground_z, robot_params, scenario_params,
                     sim_loop_params, takeoff_ground_z, tsc_params, wrench_params)
from .progress import wait_for_sim_end
from .results import finish, print_summary
from .services import call_trigger


def add_parser(sub) -> None:
    add_sim_parser(sub, "sim", stand=False)


def add_sim_parser(sub, name: str, stand: bool) -> None:
    """flip sim's or flip stand's arguments (stand's also take --controller)."""
    sp = sub.add_parser(name, help="simulator alone, zero torques" if not stand
                        else "simulator + controller holding the standing pose")
    sp.add_argument("--duration", type=POSITIVE, required=True, help="sim time, s")
    sp.add_argument("--out", required=True)
    sp.add_argument("--mode", default="lockstep", choices=["lockstep", "realtime"])
    sp.add_argument("--io", default="rcl", choices=["rcl", "python"],
                    help="how simulator and controller exchange the lockstep's per-step messages: "
                         "rcl's C API (default) or rclpy (the same messages)")
    robot_opts(sp)
    sp.add_argument("--platform", type=NONNEGATIVE)
    sp.add_argument("--ground-offset", type=FINITE)
    if stand:
        controller_opt(sp)
    graph_opts(sp)
    sp.set_defaults(func=lambda a, s=stand: cmd_sim_or_stand(a, s))


def sim_setup(args, stand: bool) -> dict:
    """run.json's start: the simulator's (and with ``stand`` the controller's) parameters, checked."""
    sim_params = {"mode": args.mode, "controller": "tsc" if stand else "none", "duration": float(args.duration),
                  "min_subscribers": SIM_MIN_SUBSCRIBERS, "rcl_io": args.io == "rcl", "linger": True,
                  **robot_params(args), **scenario_params(args), **sim_loop_params(args),
                  **wrench_params(args)}
    # held until every reader has matched on its side (the recorder reports it): lockstep before the
    # first step, realtime with a controller at step 0
    if args.mode == "lockstep" or stand:
        sim_params["hold"] = True
    return {"command": sys.argv, "kind": "stand" if stand else "sim", "sim_params": sim_params,
            "tsc_params": tsc_params(args) if stand else None,
            "landing_ground_z": landing_ground_z(args), "takeoff_ground_z": takeoff_ground_z(args)}


def start_sim_graph(graph: Graph, args, run_info: dict, stand: bool) -> float | None:
    """Recorder, live view, state publisher, (controller,) simulator started, up to the recorder
    matched on the per-step topics: the wall seconds that took, or None when the simulator ran its
    whole duration before that was seen."""
    from flip_tools.launcher import ProcessDied
    graph.start_recorder()
    graph.start_live(args, run_info)
    graph.start_state_publisher(args)
    if stand:
        graph.start_node("tsc", args, tsc_params(args))
    graph.start_node("sim", args, run_info["sim_params"])
    graph.follow_clock()
    topics = {"/clock": (1, 1), "/odom": (1, 1)}
    if stand:
        topics.update({"/joint_states": (1, 2), "/motor_command": (1, 2)})
    try:
        took = graph.watcher.wait_ready(nodes=["sim_node", "state_publisher", "flip_recorder"]
                                        + (["tsc_node"] if stand else []),
                                        topics=topics, timeout=args.ready_timeout, launcher=graph.launcher)
        took += graph.wait_recorder_matched(list(topics) + graph.foot_wrench_topics(), args.ready_timeout)
        graph.release_live()
        if run_info["sim_params"].get("hold"):
            log(call_trigger(graph.watcher, "/sim/release", args.ready_timeout))
    except ProcessDied as e:
        # the sim steps as soon as the recorder has matched (min_subscribers): a short run can
        # end, cleanly, before the readiness check has seen every node; the bag tells the rest
        if e.proc.name != "sim" or e.proc.returncode != 0:
            raise
        log("sim_node ran its whole duration before the graph check finished")
        took = None
    return took


def sim_roles(stand: bool) -> list[str]:
    """The nodes of the graph, in the order they are stopped (the recorder after them)."""
    return ["state", "tsc", "sim"] if stand else ["state", "sim"]


def simulate(graph: Graph, args, run_info: dict, stand: bool) -> int:
    """The graph started, then run for --duration s of sim time."""
    took = start_sim_graph(graph, args, run_info, stand)
    run_info["graph_ready_s"] = None if took is None else round(took, 3)
    if took is None:
        return EXIT_OK
    log(f"graph ready in {took:.2f} s (recorder matched); running {args.duration} s of sim time")
    return wait_for_sim_end(graph, float(args.duration), args.timeout, sim_roles(stand))


def cmd_sim_or_stand(args, stand: bool) -> int:
    out = Path(args.out)
    run_info = sim_setup(args, stand)
    check_live_port(args)
    prepare_out(out)        # after every argument has been checked
    extra = {"run": run_info}
    rc, graph, report = run_graph(args, out, args.mode, run_info, extra, sim_roles(stand),
                                  lambda graph: simulate(graph, args, run_info, stand))
    (out / "run.json").write_text(json.dumps(run_info, indent=2))
    summary = finish(out, graph, report, extra, "stand" if stand else "sim", landing_ground_z(args),
                     takeoff_ground_z(args))
    print(f"{out}: {'stand' if stand else 'sim'} done")
    print_summary(summary, ["outcome", "sim_duration_s", "wall_time_s", "real_time_factor", "tsc_tick_us",
                            "pelvis_height_drift_m", "final_height_above_ground_m", "final_tilt_deg"])
    if rc == EXIT_OK and stand and summary.get("outcome") != "standing":
        return EXIT_NOT_LANDED   # the controller did not hold the standing pose
    return rc
