"""summary.json of a run, computed from the bag alone (no ROS import).

Conventions (docs/architecture.md): world x forward, y left, z up; /odom pose = pelvis in world,
twist in the pelvis frame; frontflip = positive rotation about +y.

Net rotation: the pelvis z axis (body "up") projected into the world x-z plane gives the pitch
angle theta = atan2(R[0,2], R[2,2]) (= the rotation about +y for a pure pitch, defined for any
value of theta, unlike Euler pitch); it is unwrapped over time and net = theta_end - theta_start.
Cross-check: the world-frame angular velocity about y (R @ omega_body) integrated over time.

Landed (all must hold; the thresholds are in LANDING_CRITERIA and copied into the summary):
  |net rotation - expected| <= 45 deg, expected = the sum of the turns of the flips the planner
      started (their JUMPING references' ``turn``: one per flip, so a run with two backflips on one
      graph expects -720), or for bags without it +360 (frontflip) / -360 (backflip) / 0 (hop) of
      the run's kind, or +-360 when the kind is not known;
  final tilt (angle of the pelvis z axis from world z) < 20 deg;
  final pelvis height above the landing ground >= 0.6 m;
  at rest: over the last 0.5 s of sim time, |v| < 0.15 m/s and |omega| < 0.5 rad/s;
  the feet came down on the landing ground: the support centre of the TOUCH_DOWN ContactEvent after
      the first lift-off (centre of the foot contact spheres) within 0.06 m of the landing ground's
      height (a flip that came down on the ground it took off from, or short of a raised landing area,
      fails it); unknown for bags whose ContactEvent has no support_centre;
  no part but the feet touching the ground: no ContactEvent BODY_CONTACT (the sim publishes one
      when a body other than the feet starts touching the terrain; header.frame_id names the
      bodies) after the first lift-off. When the bag cannot tell (no /contact_events, or a
      ContactEvent definition without BODY_CONTACT) the check says "unknown" instead of guessing,
      is listed under "unverified", and the outcome does not depend on it.
Outcomes: landed | fell (final tilt >= 20 deg or pelvis below 0.6 m) | body_contact (upright at
the end but another body touched the ground) | off_landing_ground (upright, but the feet came down
elsewhere than on the landing ground) | under_rotated | over_rotated (upright, rotation
off) | not_at_rest (upright, rotation right, still moving) | no_data (no /odom).
For `stand`/`sim` runs: standing | fell.
A bag whose recorder died (no metadata.yaml) is recovered by the bag reader; ``bag_recovered`` says
what it kept.

Lift-off and touch-down states (``liftoff_state``, ``touchdown_state``; diagnostics, not verdicts):
the pelvis at the first lift-off and the touch-down after it (the /odom sample at or just after the
event): rotation so far and pitch rate about world y, the axis tilt (angle of the pelvis y axis, the
flywheel's axis, from world y: a somersault turns about it, so it is the roll/yaw the flip picked
up), the transverse rate (world angular velocity off the y axis) and the pelvis velocity (world).
``touchdown_com_ahead_of_feet_m``: COM x minus the feet's support centre x at that touch-down, from the
simulator's ContactEvent (negative: the feet came down ahead of the COM, as a forward landing needs).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .bag import NOT_SUMMARIZED, BagData, load_bag

LANDING_CRITERIA = {
    "rotation_tolerance_deg": 45.0,
    "max_final_tilt_deg": 20.0,
    "min_final_height_m": 0.6,
    "rest_window_s": 0.5,
    "rest_max_speed_mps": 0.15,
    "rest_max_angular_speed_radps": 0.5,
    "touchdown_ground_tolerance_m": 0.06,
}
EXPECTED_ROTATION_DEG = {"frontflip": 360.0, "backflip": -360.0, "hop": 0.0}
RPM_PER_RADPS = 60.0 / (2.0 * math.pi)
JUMPING = 1  # ContactEvent.DOMAIN_JUMPING (FlipReference.domain)
FLIGHT = 2  # ContactEvent.DOMAIN_FLIGHT
LANDING = 3  # ContactEvent.DOMAIN_LANDING
LIFT_OFF, TOUCH_DOWN = 0, 1


def quat_to_rot(q: np.ndarray) -> np.ndarray:
    """(N,4) x y z w -> (N,3,3)."""
    q = np.asarray(q, dtype=float).reshape(-1, 4)
    n = np.linalg.norm(q, axis=1, keepdims=True)
    n[n == 0] = 1.0
    x, y, z, w = (q / n).T
    R = np.empty((len(q), 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z)
    R[:, 0, 1] = 2 * (x * y - z * w)
    R[:, 0, 2] = 2 * (x * z + y * w)
    R[:, 1, 0] = 2 * (x * y + z * w)
    R[:, 1, 1] = 1 - 2 * (x * x + z * z)
    R[:, 1, 2] = 2 * (y * z - x * w)
    R[:, 2, 0] = 2 * (x * z - y * w)
    R[:, 2, 1] = 2 * (y * z + x * w)
    R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def pitch_unwrapped(quat: np.ndarray) -> np.ndarray:
    """Rotation of the pelvis about world +y, unwrapped (rad)."""
    R = quat_to_rot(quat)
    return np.unwrap(np.arctan2(R[:, 0, 2], R[:, 2, 2]))


def tilt(quat: np.ndarray) -> np.ndarray:
    """Angle between the pelvis z axis and world z (rad)."""
    R = quat_to_rot(quat)
    return np.arccos(np.clip(R[:, 2, 2], -1.0, 1.0))


def odom_time(od: dict) -> tuple[np.ndarray, str]:
    t = od.get("t")
    if t is not None and len(t) > 1 and np.ptp(t) > 0:
        return t, "header.stamp (sim time)"
    return od["t_log"], "log time (wall clock)"


def _f(x, nd=4):
    if x is None:
        return None
    x = float(x)
    return None if not math.isfinite(x) else round(x, nd)


def _stats_us(v: np.ndarray) -> dict | None:
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return None
    return {"median": _f(np.median(v), 1), "p99": _f(np.percentile(v, 99), 1), "max": _f(v.max(), 1),
            "mean": _f(v.mean(), 1), "n": int(len(v))}


def recorded_steps(data: BagData, dt: float = 0.0005) -> dict:
    """Per-step topics against the steps simulated, from step 0 to the last state in the bag
    (``/odom``'s newest stamp / dt): for /odom, /joint_states (stamp k*dt) and /motor_command (its
    ``step``) the distinct steps recorded, the steps expected and the first step missing (None: none);
    a lockstep run loses none.  ``{}`` without /odom."""
    od = data.get("/odom")
    if od is None or not len(od["t"]):
        return {}
    last = int(round(float(np.max(od["t"])) / dt))
    out = {}
    for topic in ("/odom", "/joint_states", "/motor_command"):
        d = data.get(topic)
        if d is None:
            out[topic] = {"recorded": 0, "expected": last + 1, "fraction": 0.0, "first_missing": 0}
            continue
        steps = (np.asarray(d["step"], np.int64) if topic == "/motor_command"
                 else np.rint(np.asarray(d["t"]) / dt).astype(np.int64))
        have = np.zeros(last + 1, bool)
        have[steps[(steps >= 0) & (steps <= last)]] = True
        # the last state's command may not have come before the simulator was stopped
        expected = last if topic == "/motor_command" else last + 1
        n = int(np.count_nonzero(have[:expected]))
        miss = np.flatnonzero(~have[:expected])
        out[topic] = {"recorded": n, "expected": expected, "fraction": _f(n / expected if expected else 1.0, 5),
                      "first_missing": int(miss[0]) if miss.size else None}
    return out


def summarize_bag(bag: str | Path, kind: str | None = None, landing_ground_z: float = 0.0,
                  takeoff_ground_z: float | None = None) -> dict:
    return summarize(load_bag(bag, exclude=NOT_SUMMARIZED), kind=kind, landing_ground_z=landing_ground_z,
                     takeoff_ground_z=takeoff_ground_z)


def summarize(data: BagData, kind: str | None = None, landing_ground_z: float = 0.0,
              takeoff_ground_z: float | None = None) -> dict:
    s: dict = {"bag": str(data.path), "kind": kind,
               "topics": {t: d["count"] for t, d in sorted(data.topics.items())},
               "landing_ground_z_m": landing_ground_z, "criteria": dict(LANDING_CRITERIA)}
    if data.recovered is not None:
        s["bag_recovered"] = data.recovered       # its recorder died: what the bag kept
    notes: list[str] = []
    if data.start_ns is not None and data.end_ns is not None and data.end_ns >= data.start_ns:
        s["wall_time_s"] = _f((data.end_ns - data.start_ns) * 1e-9, 3)

    _sim_time(s, data, notes)

    t_fall, body_contact = _contact_events(s, data, kind, notes)

    # ---- pelvis trajectory ---------------------------------------------------------------------
    od = data.get("/odom")
    if od is None or len(od["pos"]) < 2:
        s["outcome"] = "no_data"
        notes.append("no /odom in the bag: no verdict")
    else:
        _pelvis(s, od, data, kind, landing_ground_z, takeoff_ground_z, notes, body_contact)

    _flywheel(s, data)
    _motor_commands(s, data, t_fall)
    _planner(s, data, t_fall, notes)
    s["verdict_notes"] = notes
    return s


def _sim_time(s: dict, data: BagData, notes: list[str]) -> None:
    """Sim duration, real-time factor and the steps recorded per topic, into ``s``."""
    # ---- sim duration, real-time factor: /odom (one per step, its header stamp the step's sim time;
    # /clock comes at sim_node's clock_rate), else /clock ---------------------------------------------
    ck = data.get("/clock")
    od = data.get("/odom")
    src = ("/odom", od["t"], od["t_log"]) if od is not None and len(od["t"]) > 1 else (
        ("/clock", ck["sim_t"], ck["t_log"]) if ck is not None and len(ck["sim_t"]) > 1 else None)
    if src is not None:
        topic, st, tl = src
        s["sim_time_start_s"] = _f(st[0])
        s["sim_time_end_s"] = _f(st[-1])
        s["sim_duration_s"] = _f(st[-1] - st[0])
        # from the last arrival of the first step to the first arrival of the last one: a lockstep
        # simulator whose controller has stopped re-sends its last state every 50 ms until it is
        # stopped itself, and those copies are not stepping time; nor are the copies of the first
        # state sent before the controller answered it (its subscriptions still matching the
        # simulator's publishers: start-up, reported apart)
        first = tl[st == st[0]]
        wall = float(np.min(tl[st == st[-1]]) - np.max(first))
        s["first_state_wait_s"] = _f(float(np.max(first) - np.min(first)), 3)
        s["clock_wall_s"] = _f(wall, 3)
        s["real_time_factor"] = _f((st[-1] - st[0]) / wall, 3) if wall > 0 else None
        s["sim_time_source"] = topic
    else:
        notes.append("no /odom or /clock in the bag: no sim duration / real-time factor")
    s["recorded_steps"] = recorded_steps(data)
    for topic, r in s["recorded_steps"].items():
        if r["recorded"] < r["expected"]:
            notes.append(f"{topic}: {r['expected'] - r['recorded']} of {r['expected']} steps not in the bag "
                         f"(the first: step {r['first_missing']})")


def _contact_events(s: dict, data: BagData, kind: str | None, notes: list[str]) -> tuple[float, dict]:
    """The contact events, flight time and touch-down into ``s``; returns (the first BODY_CONTACT's
    time, inf without one; the body-contact verdict)."""
    # ---- contact events: flight time, bodies other than the feet on the ground ----------------
    ce = data.get("/contact_events")
    k = data.constants.get("flip_msgs/msg/ContactEvent") or {"LIFT_OFF": LIFT_OFF, "TOUCH_DOWN": TOUCH_DOWN}
    lift_off, touch_down, body = k.get("LIFT_OFF", LIFT_OFF), k.get("TOUCH_DOWN", TOUCH_DOWN), k.get("BODY_CONTACT")
    names = {v: n for n, v in k.items() if not n.startswith("DOMAIN_")}
    body_contact = {"ok": None, "note": "unknown: no /contact_events in the bag"}
    t_fall = np.inf                  # first BODY_CONTACT: after it the controller only damps
    if ce is not None and len(ce["event"]):
        if body is not None and np.any(ce["event"] == body):
            t_fall = float(ce["t"][np.argmax(ce["event"] == body)])
        ev, dom, t = ce["event"], ce["domain"], ce["t"]
        s["contact_events"] = [{"t": _f(t[i]), "event": names.get(int(ev[i]), int(ev[i])), "domain": int(dom[i]),
                                "step": int(ce["step"][i])} | ({"bodies": ce["frame_id"][i]}
                                                               if body is not None and ev[i] == body else {})
                               for i in range(len(ev))]
        lo = [i for i in range(len(ev)) if ev[i] == lift_off and dom[i] == FLIGHT] or \
             [i for i in range(len(ev)) if ev[i] == lift_off]
        if lo:
            td = [i for i in range(lo[0] + 1, len(ev)) if ev[i] == touch_down]
            if td:
                s["flight_time_s"] = _f(t[td[0]] - t[lo[0]])
                s["liftoff_time_s"], s["touchdown_time_s"] = _f(t[lo[0]]), _f(t[td[0]])
                # where the COM came down relative to the feet (the simulator's report; older
                # bags' ContactEvent has no support_center: NaN -> None)
                s["touchdown_com_ahead_of_feet_m"] = _f(ce["com_pos"][td[0], 0] - ce["support_center"][td[0], 0], 3)
                s["touchdown_support_z_m"] = _f(ce["support_center"][td[0], 2], 3)
                s["feet_touchdown_seen"] = True
            else:
                s["flight_time_s"] = None
                s["feet_touchdown_seen"] = False
                notes.append("lift-off without a later touch-down in /contact_events")
        else:
            s["flight_time_s"] = None
        if body is None:
            body_contact = {"ok": None, "note": "unknown: this bag's ContactEvent definition has no BODY_CONTACT"}
        else:
            t0 = t[lo[0]] if lo and kind not in ("stand", "sim") else -np.inf
            hits = [{"t": _f(t[i]), "bodies": ce["frame_id"][i]} for i in range(len(ev))
                    if ev[i] == body and t[i] >= t0]
            body_contact = {"ok": not hits, "contacts": hits,
                            "note": "BODY_CONTACT events " + ("after the first lift-off" if np.isfinite(t0)
                                                              else "in the whole run")}
    else:
        s["flight_time_s"] = None
        notes.append("no /contact_events: flight time unknown")
        if body is not None:
            # the topic was recorded but carried nothing: the sim saw no contact change at all
            if "/contact_events" in data.topics:
                body_contact = {"ok": None, "note": "unknown: /contact_events recorded but empty"}
    return t_fall, body_contact


def _flywheel(s: dict, data: BagData) -> None:
    """The flywheel's peak speed and applied torque, into ``s``."""
    # ---- joints: flywheel ----------------------------------------------------------------------
    js = data.get("/joint_states")
    if js is not None and "flywheel" in js["names"]:
        j = js["names"].index("flywheel")
        v = js["vel"][:, j]
        if np.isfinite(v).any():
            s["peak_flywheel_speed_radps"] = _f(np.nanmax(np.abs(v)), 2)
            s["peak_flywheel_rpm"] = _f(np.nanmax(np.abs(v)) * RPM_PER_RADPS, 1)
        e = js["eff"][:, j]
        if np.isfinite(e).any():
            s["peak_flywheel_torque_applied_nm"] = _f(np.nanmax(np.abs(e)), 2)


def _motor_commands(s: dict, data: BagData, t_fall: float) -> None:
    """Peak motor torques and the controller's tick times (before a fall), into ``s``."""
    # ---- motor commands: torques, controller tick ----------------------------------------------
    mc = data.get("/motor_command")
    if mc is not None and mc["effort"].size:
        eff = mc["effort"]
        peaks = {n: _f(np.nanmax(np.abs(eff[:, i])), 2) for i, n in enumerate(mc["names"])
                 if np.isfinite(eff[:, i]).any()}
        s["peak_motor_torque_nm"] = peaks
        if "flywheel" in peaks:
            s["peak_flywheel_torque_nm"] = peaks["flywheel"]
        # the controller's QP ticks: after a fall it only damps (a few us), which is not its tick time
        live = mc["t"] < t_fall
        s["tsc_tick_us"] = _stats_us(mc["compute_time_us"][live])
        if not live.all():
            s["tsc_tick_us_note"] = f"the {int(live.sum())} commands before the first BODY_CONTACT"
        s["motor_commands"] = int(len(mc["step"]))
    else:
        s["tsc_tick_us"] = None


def _planner(s: dict, data: BagData, t_fall: float, notes: list[str]) -> None:
    """The planner's references and solve times, and the tracking of them, into ``s``."""
    # ---- planner -------------------------------------------------------------------------------
    fr = data.get("/fslip/reference")
    if fr is not None and fr.get("refs"):
        refs = fr["refs"]
        s["planner"] = {
            "references": len(refs),
            "solve_time_s": [_f(r["solve_time"], 4) for r in refs],
            "solves": [{"plan_id": r["plan_id"], "domain": r["domain"], "solve_time_s": _f(r["solve_time"], 4),
                        "iterations": r["iterations"]} for r in refs],
            "max_solve_time_s": _f(max(r["solve_time"] for r in refs), 4),
            "planned_flight_time_s": _f(refs[0]["flight_time"]),
            # the jumping reference's start: where tests/offline_flip.py, and so
            # scripts/bench_landings.py --starts, re-run this flip to the bit without ROS
            "start_time_s": next((_f(r["start_time"], 4) for r in refs if r["domain"] == JUMPING), None),
            # ... from the COM x the planner measured (--x-start; unrounded: a re-run to the bit needs it all)
            "x_start_m": next((r["parameters"].get("x_start") for r in refs if r["domain"] == JUMPING), None),
            # ... in the frame of the pelvis' heading at the request (rad; m, m), as the plans are
            "heading": next(([r["parameters"][k] for k in ("heading", "heading_pivot_x", "heading_pivot_y")]
                             for r in refs if r["domain"] == JUMPING and "heading" in r["parameters"]), None),
            "planned_peak_flywheel_speed_radps": _f(max(r["peak_flywheel_speed"] for r in refs), 2),
        }
        _tracking(s, data, fr["refs"], t_fall, notes)


def _tracking(s: dict, data: BagData, refs: list[dict], t_fall: float, notes: list[str]) -> None:
    """``tracking``: the jumping and landing references against the measured outputs
    (flip_tools.tracking), and the flywheel's peak speed in the flight and in the landing."""
    from .measured import measured_outputs
    from .tracking import errors_over_plans, newest_reference, output_errors, peak_abs

    lo, td = s.get("liftoff_time_s"), s.get("touchdown_time_s")
    od = data.get("/odom")
    t_end = min(t_fall, float(od["t"][-1])) if od is not None and len(od["t"]) else t_fall
    js = data.get("/joint_states")
    if lo is not None and td is not None and js is not None and "flywheel" in js["names"]:
        v = js["vel"][:, js["names"].index("flywheel")] * RPM_PER_RADPS
        s["flight_peak_flywheel_rpm"] = _f(peak_abs(js["t"], v, lo, td), 1)
        s["landing_peak_flywheel_rpm"] = _f(peak_abs(js["t"], v, td, t_end), 1)
    m = measured_outputs(data)
    if m is None:
        notes.append("tracking: no model or state in the bag to measure the outputs")
        return
    tracking = {}
    jump = newest_reference(refs, JUMPING)
    if jump is not None and lo is not None:
        tracking["jumping"] = output_errors(m, jump, -np.inf, lo)
    lands = [r for r in refs if r["domain"] == LANDING and td is not None and r["start_time"] >= td - 1e-6]
    if lands:
        tracking["landing"] = errors_over_plans(m, lands, td, t_end)
    s["tracking"] = tracking


def _event_state(od, t, th, R, w_world, t_event):
    """Pelvis state at an event (see the module doc), or None if /odom does not cover it."""
    if t_event is None or not len(t) or t_event > t[-1]:
        return None
    i = int(np.searchsorted(t, t_event))
    v = R[i] @ od["lin"][i]
    return {"t": _f(t[i]), "rotation_deg": _f(math.degrees(th[i] - th[0]), 1),
            "pitch_rate_degps": _f(math.degrees(w_world[i, 1]), 1),
            # angle of the pelvis y axis (the flywheel's) from world y
            "axis_tilt_deg": _f(math.degrees(math.acos(min(1.0, max(-1.0, R[i, 1, 1])))), 2),
            "transverse_rate_radps": _f(math.hypot(w_world[i, 0], w_world[i, 2]), 3),
            "velocity_mps": [_f(x, 3) for x in v]}


def _on_landing_ground(support_z, ground_z, tol):
    """The touch-down's support centre (feet) at the landing ground's height (within ``tol``)."""
    if support_z is None:
        return {"ok": None, "note": "unknown: no touch-down with a support centre in /contact_events"}
    return {"ok": bool(abs(support_z - ground_z) <= tol), "support_z_m": support_z, "ground_z_m": _f(ground_z, 3)}


def _pelvis(s, od, data, kind, ground_z, takeoff_z, notes, body_contact):
    C = LANDING_CRITERIA
    t, tsrc = odom_time(od)
    s["time_base"] = tsrc
    pos, quat = od["pos"], od["quat"]
    th = pitch_unwrapped(quat)
    net = math.degrees(th[-1] - th[0])
    s["net_rotation_deg"] = _f(net, 1)
    # cross-check: integrate the world-frame pitch rate
    R = quat_to_rot(quat)
    w_world = np.einsum("nij,nj->ni", R, od["ang"])
    if len(t) > 1 and np.all(np.diff(t) >= 0):
        s["net_rotation_integrated_deg"] = _f(math.degrees(np.trapezoid(w_world[:, 1], t)), 1)
        if tsrc.startswith("header"):          # event times are sim times
            s["liftoff_state"] = _event_state(od, t, th, R, w_world, s.get("liftoff_time_s"))
            s["touchdown_state"] = _event_state(od, t, th, R, w_world, s.get("touchdown_time_s"))
    if takeoff_z is None:
        takeoff_z = 0.0
    s["takeoff_ground_z_m"] = takeoff_z
    z = pos[:, 2]
    s["initial_pelvis_z_m"] = _f(z[0])
    s["apex_pelvis_z_m"] = _f(z.max())
    s["apex_height_m"] = _f(z.max() - takeoff_z)   # pelvis (not COM) above the take-off ground
    s["apex_rise_m"] = _f(z.max() - z[0])
    s["forward_distance_m"] = _f(pos[-1, 0] - pos[0, 0])
    s["lateral_drift_m"] = _f(pos[-1, 1] - pos[0, 1])
    tl = math.degrees(tilt(quat[-1:])[0])
    s["final_tilt_deg"] = _f(tl, 1)
    s["max_tilt_deg_last_window"] = None
    h = z[-1] - ground_z
    s["final_height_above_ground_m"] = _f(h)
    s["pelvis_height_drift_m"] = _f(z[-1] - z[0])
    s["pelvis_height_range_m"] = _f(np.ptp(z))
    # at rest over the last window
    win = t >= t[-1] - C["rest_window_s"]
    if t[-1] - t[0] < C["rest_window_s"] or win.sum() < 2:
        at_rest = None
        notes.append(f"less than {C['rest_window_s']} s of /odom: at-rest unknown")
    else:
        v = np.linalg.norm(od["lin"][win], axis=1).max()
        w = np.linalg.norm(od["ang"][win], axis=1).max()
        s["rest_window_max_speed_mps"], s["rest_window_max_angular_speed_radps"] = _f(v), _f(w)
        s["max_tilt_deg_last_window"] = _f(math.degrees(tilt(quat[win]).max()), 1)
        at_rest = bool(v < C["rest_max_speed_mps"] and w < C["rest_max_angular_speed_radps"])
    s["at_rest"] = at_rest

    turns = planned_turns_deg(data)
    s["flips_started"] = None if turns is None else len(turns)
    expected = EXPECTED_ROTATION_DEG.get(kind or "") if turns is None else float(sum(turns))
    if expected is None:
        # kind not a flip (stand/sim) or unknown: nearest of +-360
        expected = 360.0 if net >= 0 else -360.0
        if kind not in (None, ""):
            expected = None
    checks = {
        "final_tilt": {"ok": bool(tl < C["max_final_tilt_deg"]), "value_deg": _f(tl, 1)},
        "final_height": {"ok": bool(h >= C["min_final_height_m"]), "value_m": _f(h)},
        "at_rest": {"ok": at_rest},
        "only_feet_touch_ground": body_contact,
    }
    if kind not in ("stand", "sim"):
        checks["touchdown_on_landing_ground"] = _on_landing_ground(s.get("touchdown_support_z_m"), ground_z,
                                                                   C["touchdown_ground_tolerance_m"])
    if expected is not None:
        checks["rotation"] = {"ok": bool(abs(net - expected) <= C["rotation_tolerance_deg"]),
                              "value_deg": _f(net, 1), "expected_deg": expected}
    s["checks"] = checks
    s["unverified"] = [n for n, c in checks.items() if c.get("ok") is None]

    _outcome(s, kind, checks, body_contact, expected, net, at_rest, notes)


def planned_turns_deg(data: BagData) -> list[float] | None:
    """The net pitch turn (deg) of each flip the planner started, in plan order: the ``turn``
    parameter of its JUMPING reference (one per flip); None when the bag's references do not carry it."""
    fr = data.get("/fslip/reference")
    turns = {r["plan_id"]: math.degrees(r["parameters"]["turn"]) for r in (fr or {}).get("refs", [])
             if r["domain"] == JUMPING and "turn" in r["parameters"]}
    return [turns[k] for k in sorted(turns)] or None


def _outcome(s, kind, checks, body_contact, expected, net, at_rest, notes):
    """``s["outcome"]`` from the checks: standing or fell (stand, sim); else the first check a flip
    failed (fell, body contact, off the landing ground, under- or over-rotated, not at rest) or landed."""
    upright = checks["final_tilt"]["ok"] and checks["final_height"]["ok"]
    if kind in ("stand", "sim"):
        s["outcome"] = "standing" if upright and body_contact.get("ok") is not False else "fell"
        return
    if not upright:
        s["outcome"] = "fell"
    elif body_contact.get("ok") is False:
        s["outcome"] = "body_contact"
    elif checks.get("touchdown_on_landing_ground", {}).get("ok") is False:
        s["outcome"] = "off_landing_ground"
    elif expected is not None and not checks["rotation"]["ok"]:
        s["outcome"] = "under_rotated" if abs(net) < abs(expected) else "over_rotated"
    elif at_rest is not True:
        s["outcome"] = "not_at_rest"
    else:
        s["outcome"] = "landed"
        if s["unverified"]:
            notes.append(f"landed on every check the bag allows; not verifiable from this bag: {s['unverified']}")
