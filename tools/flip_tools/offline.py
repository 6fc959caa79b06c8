"""A flip without ROS: cassie_flip_sim.Simulator + fslip_planner.FlipSession + tsc_controller.Controller
wired the way the node graph wires them (contact events -> planner -> references -> controller),
in one process.  For tests, benchmarks (scripts/bench_landings.py) and sweeps (flip_tools.sweep);
the nodes are the product.

Started at a graph run's start time (its jumping reference's), with ``node_state=True`` it is that
run to the bit: the controller reads the state the simulator publishes as tsc_node reads it
(:class:`NodeStateReader`: ``Simulator.state_into`` into the serialized /joint_states and /odom,
``StateConverter.from_cdr`` from their bytes) at the step's stamp (:func:`stamp`), events and
references carry stamps as the nodes' messages do (tests/graph/test_graph_flips.py compares a graph
backflip's every command).  By default it reads it with ``StateConverter.from_simulator`` (the same
numbers through ``from_ros``, whose numpy dot normalises the quaternion by the BLAS kernel's summation:
the same bits as tsc_node's only under a kernel that sums as ``from_cdr`` does)."""
from __future__ import annotations

import math

import numpy as np

from cassie_model.model import export_mjcf
from cassie_flip_sim.simulator import Simulator
from fslip_planner.heading_frame import HeadingFrame
from fslip_planner.pitch_turns import PitchTurns
from fslip_planner.plan import FLIGHT, FlipSession, MeasuredState, PelvisState
from tsc_controller import Controller, SampledReference, StateConverter

from .summary import LANDING_CRITERIA


def stamp(sim: Simulator) -> float:
    """The time of the simulator's current step as the nodes see it: its stamp, step k times the
    step in integer nanoseconds, read back as k_ns * 1e-9 (MuJoCo's ``data.time`` sums the steps and
    differs from it in the last bits, which is enough for the controller's torques to differ)."""
    return sim.step_index * round(sim.timestep * 1e9) * 1e-9


def measured(sim: Simulator, t: float | None = None) -> MeasuredState:
    """The planner's MeasuredState as sim_node's ContactEvent carries it (``t``: its stamp)."""
    p, (w, x, y, z) = sim.pelvis_pose()
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    return MeasuredState(t=stamp(sim) if t is None else t, com=sim.com_position(), com_velocity=sim.com_velocity(),
                         pitch_momentum=sim.centroidal_pitch_momentum(), pelvis_pitch=pitch,
                         pelvis_pitch_rate=float(sim.pelvis_twist("world")[1][1]),
                         support_center=sim.support_center())


class NodeStateReader:
    """(q, v) of a simulator's state as tsc_node reads it (``TscNode._state``): the state written into
    serialized /joint_states and /odom as sim_node publishes them (``Simulator.state_into`` into the
    fields of ``lockstep.RawMessage`` templates) and converted from their bytes by
    ``StateConverter.from_cdr``; the first message (a layout not yet seen) through the numpy views and
    ``from_ros``, its layout then handed on."""

    def __init__(self, conv: StateConverter, sim: Simulator):
        from flip_transport.lockstep import MessageReader, RawMessage, joint_state_layout, odometry_layout
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import JointState
        n = len(sim.joint_names)
        self.conv = conv
        self.js = RawMessage(JointState(name=list(sim.joint_names), position=[0.0] * n, velocity=[0.0] * n,
                                        effort=[0.0] * n), joint_state_layout)
        odom = Odometry(child_frame_id="pelvis")
        odom.header.frame_id = "world"
        self.od = RawMessage(odom, odometry_layout)
        self.read_js, self.read_od = MessageReader(joint_state_layout), MessageReader(odometry_layout)

    def __call__(self, sim: Simulator):
        f, o = self.js.fields, self.od.fields
        sim.state_into(f["position"], f["velocity"], f["effort"], o["pose"], o["twist"])
        js_buf, odom_buf = bytes(self.js.buf), bytes(self.od.buf)
        qv = self.conv.from_cdr(js_buf, odom_buf)
        if qv is None:
            js, od = self.read_js(js_buf), self.read_od(odom_buf)
            qv = self.conv.from_ros(self.read_js.names[0], js["position"], js["velocity"], od["pose"][:3],
                                    od["pose"][3:], od["twist"][:3], od["twist"][3:])
            self.conv.use_cdr_layout(self.read_js.layout(), self.read_od.layout())
        return qv


#: s before the jump's start at which an offline run measures the standing robot and plans (a graph
#: run's request comes while the robot stands, its plan starts a little later)
REQUEST_LEAD = 0.05


def pelvis_state(sim: Simulator) -> PelvisState:
    """The pelvis as /odom carries it (planner_node's PelvisState): pose, twist in pelvis axes; the
    flywheel's speed as /joint_states does."""
    p, (w, x, y, z) = sim.pelvis_pose()
    lin, ang = sim.pelvis_twist("local")
    fw = float(sim.joint_velocities()[list(sim.joint_names).index("flywheel")])
    return PelvisState(t=stamp(sim), position=np.array(p, float), orientation=np.array([x, y, z, w]),
                       linear_velocity=lin, angular_velocity=ang, flywheel_speed=fw)


def to_sampled(ref, start_time, plan_id=1) -> SampledReference:
    return SampledReference(ref.domain, ref.t, ref.names, ref.value, ref.d_value, ref.dd_value,
                            start_time=start_time, plan_id=plan_id, parameters=ref.parameters)


def _log_sample(log: dict, sim: Simulator, ctl: Controller, info: dict, fw_dof: int) -> None:
    """Append the state after a step to ``run``'s log."""
    p, (qw, qx, qy, qz) = sim.pelvis_pose()
    log["t"].append(sim.time)
    # angle of the pelvis y axis (the flywheel's) from world y: the roll/yaw a flip picks up
    log["axis_tilt"].append(math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (qx * qx + qz * qz)))))
    log["z"].append(p[2])
    log["x"].append(p[0])
    log["pitch"].append(ctl.pitch)
    log["H"].append(sim.centroidal_pitch_momentum())
    log["dom"].append(info["domain"])
    log["fw"].append(sim.data.qvel[fw_dof])
    lin, ang = sim.pelvis_twist('world')        # /odom's twist (norms: any frame)
    log["speed"].append(math.hypot(*lin))
    log["ang_speed"].append(math.hypot(*ang))


def _replan(kind, st, t_ev, session, ctl, turns, log, landing_reference=True):
    """A contact event's re-plan, as planner_node makes it: the flight reference at a lift-off (then the
    landings it predicts), the landing re-solve at a touch-down (given to the controller only with
    ``landing_reference``)."""
    r = None
    if kind == 0:
        r = session.flight_reference(st)
    elif kind == 1:
        r = session.landing_reference(st)
        if not landing_reference:
            r = None
    if r is not None:
        if r.domain == FLIGHT:
            turns.shift_flight(r)
        log["references"].append((t_ev, r))
        ctl.set_reference(to_sampled(r, t_ev))
    if kind == 0:
        session.predict_landing(st)
    elif kind == 1:
        turns.touch_down(st.pelvis_pitch)


def run(kind="backflip", seconds=4.0, start=0.3, sim=None, controller=None, every=20, landing_reference=True,
        node_state=False, x_start=None, heading=None, on_step=None, plant=None, turns=None, **request):
    """Run one flip; returns a log dict of arrays sampled every ``every`` steps plus events.
    ``on_step(sim, ctl, u, info)``, if given, sees every step's command before it is applied.
    ``node_state``: the controller reads the state as tsc_node does (:class:`NodeStateReader`).
    ``x_start``: the COM x the jump plan starts from (a graph run's JUMPING reference parameter
    ``x_start``, summary.json's ``planner.x_start_m``); None: measured as planner_node measures it,
    from the standing pelvis (:func:`pelvis_state`) ``REQUEST_LEAD`` s before ``start``; ``heading``
    with it: (ψ, pivot x, pivot y), summary.json's ``planner.heading`` (None: the world frame).
    ``plant``: perturbations of the simulated robot that the planner and controller are not told
    (flip_tools.perturb.Plant): it may wrap the controller's state reader (sensor noise), sees each
    contact event, and may replace each step's command (delay) or push the pelvis before the step.
    ``turns``: the somersaults turned before this flip (fslip_planner.pitch_turns.PitchTurns, as
    planner_node keeps it across requests; the run's ``turns`` in the result, for a next flip on the
    same simulator and controller)."""
    sim = sim or Simulator()
    ctl = controller or Controller(export_mjcf())
    sc = StateConverter(ctl.dyn)
    read_state = NodeStateReader(sc, sim) if node_state else sc.from_simulator
    if plant is not None:
        read_state = plant.state_reader(read_state, sc, sim)
    session = FlipSession(kind, **request)
    turns = turns if turns is not None else PitchTurns()
    start = round(start * 1e9) * 1e-9        # a stamp, as the planner's reference carries it

    def plan(state=None):
        session.x_start = x_start
        if x_start is not None and heading is not None:
            session.heading = HeadingFrame(float(heading[0]), (float(heading[1]), float(heading[2])))
        ref = session.jumping_reference(state)
        session.started(start)
        ctl.set_reference(to_sampled(ref, start))
    if x_start is not None:
        plan()
    log = dict(t=[], z=[], x=[], pitch=[], H=[], dom=[], fw=[], axis_tilt=[], speed=[], ang_speed=[], events=[],
               t_step=[], fw_step=[],
               references=[], event_states=[], fell=None)
    fw_dof = sim.model.jnt_dofadr[sim.model.joint("flywheel").id]
    while sim.time < seconds:
        if session.result is None and stamp(sim) >= start - REQUEST_LEAD:
            plan(pelvis_state(sim))
        for ev in sim.pop_events():
            # stamped like sim_node's ContactEvent: the step at which the event is reported (its state
            # is that step's), not the onset (a lift-off is reported 20 steps after its onset)
            t_ev = stamp(sim)
            log["events"].append((int(ev.kind), t_ev))
            ctl.on_contact_event(int(ev.kind), t_ev)
            if plant is not None:
                plant.on_event(ev)
            st = measured(sim, t_ev)
            log["event_states"].append((int(ev.kind), st))
            _replan(int(ev.kind), st, t_ev, session, ctl, turns, log, landing_reference)
        q, v = read_state(sim)
        u, info = ctl.compute(q, v, stamp(sim))
        if on_step is not None:
            on_step(sim, ctl, u, info)
        if plant is not None:
            u = plant.command(sim, u)
        sim.step(u)
        # the flywheel at every step, for its peaks (issue 22); stamped as the events are, so that the
        # touch-down's sample is in both the flight's window and the landing's, as in summary.json
        log["t_step"].append(stamp(sim))
        log["fw_step"].append(sim.data.qvel[fw_dof])
        if sim.step_index % every == 0:
            _log_sample(log, sim, ctl, info, fw_dof)
        if sim.body_contacts():
            log["fell"] = sim.time
            break
    out = {k: (np.array(v) if k not in ("events", "references", "event_states", "fell") else v)
           for k, v in log.items()}
    out.update(sim=sim, ctl=ctl, session=session, turns=turns)
    return out


# ------------------------------------------------------------------ the landing verdict
#: net rotation of each somersault (rad) and how far off a landed one may be
EXPECTED_TURN = {"backflip": -2 * math.pi, "frontflip": 2 * math.pi}
TURN_TOLERANCE = 0.3
#: lowest final pelvis height above the landing ground of a landed flip (m)
MIN_FINAL_HEIGHT = 0.8


def feet_apart(sim: Simulator) -> tuple[float, float]:
    """The stance the simulator's robot stands in: (how far the left foot's centre is ahead of the
    right's along the feet's mean heading, m; left foot's yaw less the right's, rad), from the
    MuJoCo toe and heel sites.  A landing that leaves one foot ahead or turned is the stance the next
    flip jumps from (a backflip from a stance with one foot 4 mm ahead rolled over in its landing:
    tsc_controller's ``leg_symmetry`` gain)."""
    m, d = sim.model, sim.data
    feet = {}
    for side in ("left", "right"):
        toe, heel = (d.site_xpos[m.site(f"{side}_foot_{k}").id][:2] for k in ("toe", "heel"))
        feet[side] = (0.5 * (toe + heel), math.atan2(toe[1] - heel[1], toe[0] - heel[0]))
    (cl, yl), (cr, yr) = feet["left"], feet["right"]
    h = np.array([math.cos(yl) + math.cos(yr), math.sin(yl) + math.sin(yr)])
    h /= max(float(np.linalg.norm(h)), 1e-12)
    yaw = (yl - yr + math.pi) % (2.0 * math.pi) - math.pi
    return float((cl - cr) @ h), yaw


def lift_off_touch_down(events) -> tuple:
    """(time of the first lift-off, time of the first touch-down after it) of a run's events; None
    where there is none."""
    lo = next((t for k, t in events if k == 0), None)
    td = next((t for k, t in events if k == 1 and lo is not None and t > lo), None)
    return lo, td


def at_rest(t, speed, ang_speed, criteria=LANDING_CRITERIA) -> bool:
    """`flip run`'s at-rest check (flip_tools.summary) on a run's samples: over the last
    ``rest_window_s`` the pelvis' speed and angular speed stay below their limits."""
    t = np.asarray(t)
    win = t >= t[-1] - criteria["rest_window_s"]
    return bool(np.max(np.asarray(speed)[win]) < criteria["rest_max_speed_mps"]
                and np.max(np.asarray(ang_speed)[win]) < criteria["rest_max_angular_speed_radps"])


def outcome(r: dict, kind: str, ground: float = 0.0, pitch_end: float | None = None) -> str:
    """How a run of :func:`run` ended: ``fell`` (a body other than the feet touched the ground, or
    the pelvis ended below ``MIN_FINAL_HEIGHT`` above ``ground``), ``wrong_rotation`` (no touch-down
    after a lift-off, or the final pitch more than ``TURN_TOLERANCE`` off one turn), ``not_at_rest``
    (:func:`at_rest`) or ``landed``.  ``pitch_end``: the final pelvis pitch (default: the
    controller's estimate, ``r["pitch"]``)."""
    if r["fell"] is not None or float(r["z"][-1]) - ground <= MIN_FINAL_HEIGHT:
        return "fell"
    pitch_end = float(r["pitch"][-1]) if pitch_end is None else pitch_end
    if lift_off_touch_down(r["events"])[1] is None or not abs(pitch_end - EXPECTED_TURN[kind]) < TURN_TOLERANCE:
        return "wrong_rotation"
    return "landed" if at_rest(r["t"], r["speed"], r["ang_speed"]) else "not_at_rest"
