"""`flip sweep --mode graph`: a sample (flip, knobs, seed) run through the node graph, as `flip run`
in a child process (its own ROS domain, claimed by `flip run`), the knobs given to sim_node only
(the planner and the controller are not told), judged from the run's bag (summary.json) and
written as the same record an offline sample gives (flip_tools.perturb.run_sample).

Where the graph applies each knob: ``ground_offset`` is the terrain sim_node builds (`flip run
--ground-offset`, with a platform sim_node's ``landing_height``); ``friction``, ``mass_scale``,
``com_offset``, ``torque_scale``, ``delay_steps``, ``push``, ``push_phase`` are sim_node's ``plant``
parameter (cassie_flip_sim.perturbation, the definitions the offline runner uses); ``seconds`` is
the run's sim duration; ``start``: the request goes ``START_LEAD_S`` before it (the planner starts a
plan that much after the request), the jump then starts later by the request's latency and the
plan's solve (the record's ``jump_start_s``).  The noise knobs are refused (:data:`REFUSED`).
"""
from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

from . import perturb as P

#: CPUs a graph takes (the simulator and controller share one in lockstep; the planner, the
#: recorder and this tool's process the other)
GRAPH_CPUS = 2
#: s between the request and the start of the jump it plans (fslip_planner.planner_node.START_LEAD_S)
START_LEAD_S = 0.25
#: the knobs a graph run cannot apply, and why
REFUSED = {
    "joint_noise": "sensor noise would go into the /joint_states the bag records and the verdict reads "
                   "(offline, only the controller reads it noisy)",
    "imu_noise": "sensor noise would go into the /odom the bag records and the planner and the verdict read "
                 "(offline, only the controller reads it noisy)",
}
#: the plant knobs passed to sim_node (its ``plant`` parameter)
PLANT = ("friction", "mass_scale", "com_offset", "torque_scale", "delay_steps", "push", "push_phase")
#: summary.json's outcome -> the sweep's (flip_tools.perturb.OUTCOMES; the offline verdict's names)
OUTCOME = {"landed": "landed", "fell": "fell", "body_contact": "fell", "not_at_rest": "not_at_rest",
           "under_rotated": "wrong_rotation", "over_rotated": "wrong_rotation",
           "off_landing_ground": "off_landing_ground", "rejected": "rejected"}
#: wall seconds a graph sample may take beyond its sim time before it is stopped (an `error`)
TIMEOUT_BASE_S, TIMEOUT_PER_SIM_S = 240.0, 30.0


def refusal(samples) -> str | None:
    """Why the samples cannot run through the graph (a knob of :data:`REFUSED` set off its
    default), or None."""
    used = sorted({k for s in samples for k, v in s.knobs.items() if k in REFUSED and v != P.KNOBS[k][0]})
    if not used:
        return None
    return ("--mode graph cannot apply " + ", ".join(used) + ": "
            + "; ".join(f"{k}: {REFUSED[k]}" for k in used) + ". Run these samples offline (--mode offline)")


def run_args(sample: P.Sample, out: Path) -> list[str]:
    """`flip run`'s arguments for a sample: the flip's request, the robot, the terrain, the plant
    knobs (--plant), the request time and the sim duration."""
    flip = P.FLIPS[sample.flip]
    args = ["run", flip.kind, "--robot", P.ROBOT, "--apex", repr(flip.apex), "--distance", repr(flip.distance),
            "--duration", repr(sample.knob("seconds")),
            "--request-at", repr(max(sample.knob("start") - START_LEAD_S, 0.0)),
            "--out", str(out), "--no-plots", "--timeout", repr(timeout_s(sample))]
    if flip.platform:
        args += ["--platform", repr(flip.platform)]
    ground = flip.ground_offset + sample.knob("ground_offset")
    if ground:
        args += ["--ground-offset", repr(ground)]
    plant = {k: v for k, v in sample.knobs.items() if k in PLANT}
    if plant:
        args += ["--plant", *(f"{k}={v}" for k, v in sorted(plant.items()))]
    return args


def timeout_s(sample: P.Sample) -> float:
    return TIMEOUT_BASE_S + TIMEOUT_PER_SIM_S * sample.knob("seconds")


def result_from_run(sample: P.Sample, out: Path, returncode: int, log_tail: str) -> dict:
    """The sample's record from a finished `flip run` in ``out`` (summary.json; its exit code and
    the end of its log when there is no summary)."""
    res = P.failed_result(sample, None, mode="graph")
    summary_file = out / "summary.json"
    if not summary_file.exists():
        res["error"] = f"flip run exited {returncode} without a summary: {log_tail[-500:]}"
        return res
    s = json.loads(summary_file.read_text())
    raw = s.get("outcome")
    if raw == "rejected":
        reason = (s.get("response") or {}).get("reason") or ""
        named = re.match(r"([a-z_]+): ", reason)          # e.g. "not_standing: ...", the planner's limit
        res.update(outcome="rejected", error=reason, limit=named[1] if named else None)
        return res
    outcome = OUTCOME.get(raw)
    if outcome is None:
        res["error"] = f"flip run's outcome {raw!r} (exit {returncode}): {s.get('error') or log_tail[-300:]}"
        return res
    contacts = ((s.get("checks") or {}).get("only_feet_touch_ground") or {}).get("contacts") or []
    res.update(outcome=outcome, net_rotation_deg=s.get("net_rotation_deg"),
               fell_at_s=contacts[0]["t"] if contacts else None, touchdown_s=s.get("touchdown_time_s"),
               peak_flywheel_rpm=s.get("peak_flywheel_rpm"), sim_s=s.get("sim_time_end_s"),
               jump_start_s=(s.get("planner") or {}).get("start_time_s"))
    return res


def run_graph_sample(record: dict, runs_dir: str, keep_bag: bool = False) -> dict:
    """Run one sample through the graph (`flip run` in ``runs_dir/<sample id>``, its output in
    ``runs_dir/<sample id>.log``); its record, as flip_tools.perturb.run_sample's.  The bag is deleted
    after the summary unless ``keep_bag``."""
    sample = P.Sample(**record)
    t0 = time.perf_counter()
    out = Path(runs_dir) / sample.id
    if out.exists():
        shutil.rmtree(out)           # a run a stopped sweep left: this sample starts again
    out.parent.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "flip_tools.cli", *run_args(sample, out)]
    limit = timeout_s(sample) + 60.0      # `flip run --timeout` stops it first; this is the backstop
    with open(out.parent / f"{sample.id}.log", "w+") as logf:
        logf.write(" ".join(cmd) + "\n")
        logf.flush()
        # a Ray worker blocks SIGINT and a child inherits the mask: unblocked for the child, or the
        # graph's nodes would not see the launcher's stop (each would wait out its SIGTERM timeout)
        mask = signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        try:
            # its own session: on the backstop's timeout the whole graph is stopped, not `flip run` alone
            proc = subprocess.Popen(cmd, stdout=logf, stderr=subprocess.STDOUT, start_new_session=True)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        try:
            rc = proc.wait(timeout=limit)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGINT)
            try:
                rc = proc.wait(timeout=30.0)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                rc = proc.wait()
        logf.seek(0)
        tail = logf.read()[-2000:]
    res = result_from_run(sample, out, rc, tail)
    if rc != 0 and res["outcome"] == "error" and not res["error"]:
        res["error"] = f"flip run exited {rc}: {tail[-500:]}"
    if not keep_bag and (out / "bag").exists():
        shutil.rmtree(out / "bag")
    res["wall_s"] = time.perf_counter() - t0
    return res
