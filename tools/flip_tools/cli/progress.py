"""How a run follows its graph to the end: sim time reached, the touch-down seen, the simulator's
own end, a stall or a node that died."""
from __future__ import annotations

import os
import time

from .common import EXIT_OK, log
from .graph import Graph, sim_lingers

STALL_TIMEOUT_S = float(os.environ.get("FLIP_STALL_TIMEOUT", "120"))
END_TOLERANCE_S = 0.001   # sim time short of the end that counts as the end (2 steps at 2 kHz)
#: sim seconds a jump takes from its request to lift-off at most (planning, START_LEAD, stance): the run's
#: end is bounded by it until the touch-down is seen
JUMP_ALLOWANCE_S = 5.0


def wait_sim_time(graph: Graph, t: float, wall_timeout: float) -> float:
    """Until sim time has reached ``t`` (the robot settling on its feet); the sim time then."""
    end = time.monotonic() + wall_timeout
    while (now := graph.sim_now()) is None or now < t:
        graph.launcher.check_alive()
        if time.monotonic() > end:
            raise TimeoutError(f"sim time {now} has not reached {t:g} s after {wall_timeout:.0f} s wall")
        graph.spin(0.02)
    return now


def landing_end(graph: Graph, since: float, until: float, settle: float, run_info: dict):
    """The run's end in sim time as a callable: ``settle`` s after the first touch-down or body
    contact later than ``since``, ``until`` while none has come (run_info's "touch_down_sim_time")."""
    from flip_msgs.msg import ContactEvent
    graph.follow_contact_events()
    ends = (ContactEvent.TOUCH_DOWN, ContactEvent.BODY_CONTACT)
    state = {"end": until}

    def end() -> float:
        for event, t in graph.contact_events():
            if event in ends and t > since and "touch_down_sim_time" not in run_info:
                run_info["touch_down_sim_time"] = round(t, 4)
                state["end"] = t + settle
        return state["end"]
    return end


def wait_for_sim_end(graph: Graph, end_sim, wall_timeout: float, roles) -> int:
    """Until the sim exits by itself (its duration), or sim time reaches end_sim (a number, or a
    callable giving it, asked anew each time) (then the tool
    stops it), or the wall-clock timeout, or sim time stands still for STALL_TIMEOUT_S wall
    seconds (sim_node holds at most 30 s for the planner). A node other than the sim dying ends
    the run."""
    t_end = time.monotonic() + wall_timeout
    L = graph.launcher
    last_t, last_change = None, time.monotonic()
    while True:
        graph.spin(0.1)      # nothing high-rate is on this executor: this waits up to 0.1 s
        now = graph.sim_now()
        if now != last_t:
            last_t, last_change = now, time.monotonic()
        elif time.monotonic() - last_change > STALL_TIMEOUT_S:
            raise TimeoutError(f"sim time stuck at {now} for {STALL_TIMEOUT_S:.0f} s wall "
                               f"(is the sim waiting for subscribers or the controller? see {graph.out / 'logs'})")
        sim = L.procs["sim"]
        if sim.poll() is not None:
            log(f"sim_node exited by itself (code {sim.returncode}) at sim t = {graph.sim_time}")
            return EXIT_OK
        if sim_lingers(graph):
            log(f"sim_node ran its duration (sim t = {graph.sim_time}); it keeps its publishers until stopped")
            return EXIT_OK
        for r in roles:
            p = L.procs.get(r)
            if p is not None and r != "sim" and p.poll() is not None:
                raise RuntimeError(f"{r} exited (code {p.returncode}) during the run:\n{p.log_tail()}")
        graph.check_live()
        if L.procs["recorder"].poll() is not None:
            raise RuntimeError(f"recorder exited (code {L.procs['recorder'].returncode}):\n"
                               f"{L.procs['recorder'].log_tail()}")
        # (a sim that ran its duration and lingers shows its last state's time, a step short)
        end = end_sim() if callable(end_sim) else end_sim
        if graph.sim_time is not None and graph.sim_time >= end - END_TOLERANCE_S:
            log(f"sim time {graph.sim_time:.2f} s reached the end ({end:.2f} s); stopping the sim")
            return EXIT_OK
        if time.monotonic() > t_end:
            raise TimeoutError(f"wall-clock timeout {wall_timeout:.0f} s (sim t = {graph.sim_time})")
