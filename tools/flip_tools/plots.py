"""PNG plots of a run from its bag (matplotlib Agg; no ROS import), after the paper's Fig. 6.

fig6.png      pitch momentum (planned per domain vs. measured: recomputed from /joint_states + /odom
              with the model on /robot_description_mjcf, flywheel share too), leg length,
              ground normal force (the paper's panel (c): the feet's wrench topics in world axes,
              both feet's total and each, against the FSLIP's force of the ground references,
              fslip_planner.plan_geometry.ground_force, and m·g), x_com, pelvis pitch (planned vs.
              /odom), flywheel torque and speed — each panel shows what the bag holds and says
              "not in the bag" otherwise.
pelvis.png    pelvis x, z, pitch (unwrapped), tilt over sim time.
torques.png   the 11 commanded motor torques.
tsc_tick.png  histogram of MotorCommand.compute_time_us.
scene.png     side view (x, z) of the robot's links at the crouch, lift-off, apex, touch-down and end
              (the model on /robot_description_mjcf posed by /joint_states + /odom, the poses /tf
              carries), the measured COM path, and the planner's /fslip/com_path and /fslip/targets.
Domains (from /contact_events and the plan's start) are shaded in every time plot.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .bag import NOT_SUMMARIZED, BagData, load_bag  # noqa: E402
from .measured import foot_wrenches_world, measured_outputs, robot_mass  # noqa: E402
from .summary import odom_time, pitch_unwrapped, tilt  # noqa: E402

DOMAIN_NAMES = {0: "standing", 1: "jumping", 2: "flight", 3: "landing"}
DOMAIN_COLORS = {0: "#ffffff", 1: "#fff3d6", 2: "#dcecff", 3: "#e3f5e1"}



def _save(fig, path, rect=None):
    """Lay the figure out (``rect``: the area left for the axes), write it at 110 dpi, close it."""
    fig.tight_layout(**({} if rect is None else {"rect": rect}))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

def plot_bag(bag: str | Path, out_dir: str | Path, data: BagData | None = None) -> list[Path]:
    data = data or load_bag(bag, exclude=NOT_SUMMARIZED)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = [_fig6(data, out / "fig6.png"), _pelvis(data, out / "pelvis.png"),
             _torques(data, out / "torques.png"), _tick(data, out / "tsc_tick.png"), _scene(data, out / "scene.png")]
    return [f for f in files if f is not None]


# ---------------------------------------------------------------------------------------------
def _refs(data):
    fr = data.get("/fslip/reference")
    return fr["refs"] if fr else []


def _ref_series(data, name):
    """[(domain, t_abs, value)] of one reference output, newest plan only, each reference up to the
    start of the next one (a landing re-solved after a rebound replaces the first one from then on:
    the plot shows what the controller was given at each time)."""
    refs = _refs(data)
    if not refs:
        return []
    last_plan = refs[-1]["plan_id"]
    plan = sorted((r for r in refs if r["plan_id"] == last_plan), key=lambda r: r["start_time"])
    out = []
    for i, r in enumerate(plan):
        if name not in r["output_names"]:
            continue
        v = np.asarray(r["value"])
        if v.ndim != 2:
            continue
        t = r["start_time"] + np.asarray(r["t"], float)
        keep = t <= plan[i + 1]["start_time"] if i + 1 < len(plan) else np.ones(len(t), bool)
        out.append((r["domain"], t[keep], v[keep, r["output_names"].index(name)]))
    return out


def planned_normal_force(data):
    """[(domain, t_abs, Fz)] of the FSLIP's ground force along each ground reference of the newest
    plan, each up to the start of the next one as ``_ref_series`` draws them
    (fslip_planner.plan_geometry.ground_force, the reference's fslip_mass and leg_offset; a
    reference without them (older bags, a fallback landing) uses the robot's mass and L as r)."""
    from fslip_planner.plan_geometry import ground_force
    refs = _refs(data)
    if not refs:
        return []
    plan = sorted((r for r in refs if r["plan_id"] == refs[-1]["plan_id"]), key=lambda r: r["start_time"])
    mass, out = None, []
    for i, r in enumerate(plan):
        p = r["parameters"]
        m = p.get("fslip_mass")
        if m is None:
            mass = robot_mass(data) if mass is None else mass
            m = mass
        if m is None or np.ndim(r["value"]) != 2:
            continue
        f = ground_force(r["t"], r["output_names"], r["value"], r["d_value"], r["dd_value"], m,
                         p.get("leg_offset", 0.0))
        if f is not None:
            t = r["start_time"] + f["t"]
            keep = t <= plan[i + 1]["start_time"] if i + 1 < len(plan) else np.ones(len(t), bool)
            out.append((r["domain"], t[keep], f["Fz"][keep]))
    return out


def _domain_spans(data):
    """[(t0, t1, domain)] from the first JUMPING reference start and the contact events."""
    marks = []
    for r in _refs(data):
        if r["domain"] == 1:
            marks.append((r["start_time"], 1))
            break
    ce = data.get("/contact_events")
    if ce is not None:
        marks += [(float(t), int(d)) for t, d in zip(ce["t"], ce["domain"])]
    marks.sort()
    t_end = None
    od = data.get("/odom")
    if od is not None and len(od["pos"]):
        t_end = float(odom_time(od)[0][-1])
    spans = []
    for i, (t0, d) in enumerate(marks):
        t1 = marks[i + 1][0] if i + 1 < len(marks) else t_end
        if t1 is not None and t1 > t0:
            spans.append((t0, t1, d))
    return spans


def _shade(ax, spans):
    for t0, t1, d in spans:
        ax.axvspan(t0, t1, color=DOMAIN_COLORS.get(d, "#eeeeee"), alpha=0.8, lw=0, zorder=0)


def _missing(ax, what):
    ax.text(0.5, 0.5, f"{what}: not in the bag", ha="center", va="center", transform=ax.transAxes,
            color="0.4", fontsize=9)


def _plot_ref(ax, data, name, scale=1.0, label="planned", turns=None):
    """The newest plan's ``name`` (:func:`_ref_series`).  ``turns``: (t, angle) of the measured
    angle (rad): each reference is drawn on the measured turn it starts in (a landing plans the pelvis
    near 0 rad; after a somersault the pelvis is there at ±2π)."""
    series = _ref_series(data, name)
    for i, (dom, t, v) in enumerate(series):
        if turns is not None and len(t) and len(turns[0]):
            at = float(np.interp(t[0], *turns))
            v = v + 2 * np.pi * np.round((at - v[0]) / (2 * np.pi))
        ax.plot(t, v * scale, "--", color="C3", lw=1.5, label=label if i == 0 else None)
    return bool(series)


# ---------------------------------------------------------------------------------------------
def _fig6(data, path):
    fig, axs = plt.subplots(7, 1, figsize=(8, 15), sharex=True)
    spans = _domain_spans(data)
    for ax in axs:
        _shade(ax, spans)
    ce = data.get("/contact_events")
    od = data.get("/odom")
    js = data.get("/joint_states")
    mc = data.get("/motor_command")
    m = measured_outputs(data)

    ax = axs[0]
    ax.set_ylabel("pitch momentum\n(kg m²/s)")
    have = _plot_ref(ax, data, "H_pitch")
    if m is not None:
        ax.plot(m["t"], m["H_pitch"], color="C0", lw=1, label="measured H_pitch")
        ax.plot(m["t"], m["H_flywheel"], color="C2", lw=1, label="measured H_flywheel")
        have = True
    if ce is not None and len(ce["t"]):
        ax.plot(ce["t"], ce["H_pitch"], "o", color="C0", label="measured (contact events)")
        have = True
    if not have:
        _missing(ax, "H_pitch")

    ax = axs[1]
    ax.set_ylabel("leg length L (m)")
    have = _plot_ref(ax, data, "L")
    if m is not None:
        ax.plot(m["t"], m["L"], color="C0", lw=1, label="measured")
        have = True
    if not have:
        _missing(ax, "L")

    _fig6_normal_force(axs, data, ce)

    ax = axs[3]
    ax.set_ylabel("x_com (m)")
    have = _plot_ref(ax, data, "x_com")
    if od is not None and len(od["pos"]):
        t, _ = odom_time(od)
        ax.plot(t, od["pos"][:, 0], color="0.5", lw=1, label="pelvis x (/odom)")
        have = True
    if m is not None:
        ax.plot(m["t"], m["x_com"], color="C0", lw=1, label="measured x_com")
    if ce is not None and len(ce["t"]):
        ax.plot(ce["t"], ce["com_pos"][:, 0], "o", color="C0", label="COM x (contact events)")
        have = True
    if not have:
        _missing(ax, "x_com")

    ax = axs[4]
    ax.set_ylabel("pelvis pitch (deg)")
    pitch = (odom_time(od)[0], pitch_unwrapped(od["quat"])) if od is not None and len(od["pos"]) > 1 else None
    have = _plot_ref(ax, data, "phi_pitch", scale=180 / np.pi, turns=pitch)
    if pitch is not None:
        ax.plot(pitch[0], np.degrees(pitch[1]), color="C0", label="measured (/odom)")
        have = True
    if not have:
        _missing(ax, "/odom")

    _fig6_flywheel(axs, mc, js)

    for ax in axs:
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="best")
        ax.grid(alpha=0.3)
    handles = [plt.Rectangle((0, 0), 1, 1, color=DOMAIN_COLORS[d]) for d in (1, 2, 3)]
    fig.legend(handles, [DOMAIN_NAMES[d] for d in (1, 2, 3)], loc="upper center", ncol=3, fontsize=8)
    return _save(fig, path, rect=(0, 0, 1, 0.98))


def _fig6_normal_force(axs, data, ce):
    """Fig. 6's normal-force panel: measured (wrench topics, contact events) and planned (FSLIP)."""
    ax = axs[2]
    ax.set_ylabel("normal force (N)")
    have = False
    w = foot_wrenches_world(data)
    if w is not None:
        fz = w["force"][:, :, 2]
        ax.plot(w["t"], fz.sum(axis=1), color="C0", lw=1.2, label="measured, both feet (wrench topics)")
        ax.plot(w["t"], fz[:, 0], color="C0", lw=0.6, alpha=0.5, label="left foot")
        ax.plot(w["t"], fz[:, 1], color="C1", lw=0.6, alpha=0.5, label="right foot")
        have = True
    for i, (_dom, t, f) in enumerate(planned_normal_force(data)):
        ax.plot(t, f, "--", color="C3", lw=1.5, label="FSLIP (plan)" if i == 0 else None)
        have = True
    if ce is not None and len(ce["t"]):
        ax.plot(ce["t"], ce["left_normal_force"] + ce["right_normal_force"], "o", color="C0", ms=4,
                label="both feet (contact events)")
        have = True
    mass = robot_mass(data) if have else None
    if mass is not None:
        ax.axhline(mass * 9.81, color="0.4", lw=0.8, ls=":", label=f"m g = {mass * 9.81:.0f} N")
    if not have:
        _missing(ax, "normal force")


def _fig6_flywheel(axs, mc, js):
    """Fig. 6's flywheel panels: torque commanded and applied, speed."""
    ax = axs[5]
    ax.set_ylabel("flywheel torque\n(N m)")
    have = False
    if mc is not None and "flywheel" in mc["names"]:
        ax.plot(mc["t"], mc["effort"][:, mc["names"].index("flywheel")], color="C0", lw=1, label="commanded")
        have = True
    if js is not None and "flywheel" in js["names"]:
        ax.plot(js["t"], js["eff"][:, js["names"].index("flywheel")], color="C2", lw=1, alpha=0.7,
                label="applied (/joint_states)")
        have = True
    if not have:
        _missing(ax, "flywheel torque")

    ax = axs[6]
    ax.set_ylabel("flywheel speed\n(rpm)")
    if js is not None and "flywheel" in js["names"]:
        ax.plot(js["t"], js["vel"][:, js["names"].index("flywheel")] * 60 / (2 * np.pi), color="C0")
    else:
        _missing(ax, "flywheel speed")
    ax.set_xlabel("sim time (s)")


def _pelvis(data, path):
    od = data.get("/odom")
    if od is None or len(od["pos"]) < 2:
        return None
    t, src = odom_time(od)
    fig, axs = plt.subplots(4, 1, figsize=(8, 9), sharex=True)
    spans = _domain_spans(data)
    for ax in axs:
        _shade(ax, spans)
    axs[0].plot(t, od["pos"][:, 0])
    axs[0].set_ylabel("x (m)")
    axs[1].plot(t, od["pos"][:, 2])
    axs[1].set_ylabel("z (m)")
    axs[2].plot(t, np.degrees(pitch_unwrapped(od["quat"])))
    axs[2].set_ylabel("pitch about +y (deg)")
    axs[3].plot(t, np.degrees(tilt(od["quat"])))
    axs[3].set_ylabel("tilt (deg)")
    axs[3].set_xlabel(f"time (s, {src})")
    for ax in axs:
        ax.grid(alpha=0.3)
    return _save(fig, path)


def _torques(data, path):
    mc = data.get("/motor_command")
    if mc is None or not mc["effort"].size:
        return None
    fig, ax = plt.subplots(figsize=(9, 5))
    _shade(ax, _domain_spans(data))
    for i, n in enumerate(mc["names"]):
        ax.plot(mc["t"], mc["effort"][:, i], lw=1, label=n)
    ax.set_xlabel("sim time (s)")
    ax.set_ylabel("commanded torque (N m)")
    ax.legend(fontsize=7, ncol=2)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def _tick(data, path):
    mc = data.get("/motor_command")
    if mc is None or not len(mc["compute_time_us"]):
        return None
    v = mc["compute_time_us"]
    v = v[np.isfinite(v)]
    if not len(v):
        return None
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.hist(v, bins=80)
    med, p99 = np.median(v), np.percentile(v, 99)
    ax.axvline(med, color="C1", label=f"median {med:.0f} µs")
    ax.axvline(p99, color="C3", label=f"p99 {p99:.0f} µs")
    ax.set_xlabel("controller tick (µs, MotorCommand.compute_time_us)")
    ax.set_ylabel("ticks")
    ax.legend()
    return _save(fig, path)


# ---------------------------------------------------------------------------------------------
def scene_instants(data) -> list[tuple[str, float]]:
    """(label, sim time) of the moments scene.png draws: 0.3 s before the lift-off (the crouch), the
    lift-off, the flight's middle, the touch-down after it, and the end of the run; without a flight,
    the start and the end."""
    od = data.get("/odom")
    if od is None or not len(od["t"]):
        return []
    t_end = float(od["t"][-1])
    ce = data.get("/contact_events")
    lo = td = None
    if ce is not None and len(ce["t"]):
        ev = np.asarray(ce["event"])
        los = np.flatnonzero(ev == 0)
        if len(los):
            lo = float(ce["t"][los[0]])
            tds = [float(ce["t"][i]) for i in np.flatnonzero(ev == 1) if ce["t"][i] > lo]
            td = tds[0] if tds else None
    if lo is None or td is None:
        return [("start", float(od["t"][0])), ("end", t_end)]
    return [("crouch", max(float(od["t"][0]), lo - 0.3)), ("lift-off", lo), ("mid-flight", 0.5 * (lo + td)),
            ("touch-down", td), ("end", t_end)]


def _scene(data, path):
    """scene.png (module doc): what a 3D view of the run's /tf, /fslip/com_path and /fslip/targets
    shows, from the side, one panel per moment of :func:`scene_instants`."""
    import mujoco

    from .measured import bag_mjcf
    from .video import frame_rows, qpos_from_bag
    mjcf, js, od = bag_mjcf(data), data.get("/joint_states"), data.get("/odom")
    instants = scene_instants(data)
    if not mjcf or js is None or od is None or not len(js["t"]) or not instants:
        return None
    try:
        model = mujoco.MjModel.from_xml_string(mjcf)
    except Exception:  # noqa: BLE001 - a description that is not a loadable model (a stand-in's)
        return None
    if model.nbody < 2:                     # a description without a robot body (a stand-in's)
        return None
    mdata = mujoco.MjData(model)
    frames = qpos_from_bag(model, js, od, fps=200.0)
    t_frames = np.array([float(js["t"][i]) for i, _ in frame_rows(js, od, 200.0)])
    if not len(t_frames):
        return None

    def pose(k):
        mdata.qpos[:] = frames[k]
        mujoco.mj_kinematics(model, mdata)
        mujoco.mj_comPos(model, mdata)
        segs = [(mdata.xpos[model.body_parentid[b]].copy(), mdata.xpos[b].copy()) for b in range(2, model.nbody)]
        return segs, mdata.subtree_com[1].copy()
    com = np.array([pose(k)[1] for k in range(len(t_frames))])
    plans = [np.array([[ps.pose.position.x, ps.pose.position.z] for ps in msg.poses])
             for msg in (data.get("/fslip/com_path") or {}).get("msgs", [])]
    targets = [(m.pose.position.x, m.pose.position.z) for msg in (data.get("/fslip/targets") or {}).get("msgs", [])
               for m in msg.markers if m.action == 0]                              # ADD
    xs = np.r_[com[:, 0], *[p[:, 0] for p in plans if len(p)]]
    x0, x1 = float(np.min(xs)) - 0.7, float(np.max(xs)) + 0.7
    fig, axs = plt.subplots(1, len(instants), figsize=(2.6 * len(instants), 4.2), sharey=True)
    for ax, (label, t) in zip(np.atleast_1d(axs), instants):
        k = int(np.argmin(np.abs(t_frames - t)))
        segs, c = pose(k)
        for i, p in enumerate(plans):
            if len(p):
                ax.plot(p[:, 0], p[:, 1], "--", color="C3", lw=1, label="/fslip/com_path" if i == 0 else None)
        if targets:
            ax.plot(*np.array(targets).T, "o", color="C1", ms=5, label="/fslip/targets")
        ax.plot(com[:k + 1, 0], com[:k + 1, 2], color="C0", lw=1, label="COM (measured)")
        for a, b in segs:
            ax.plot([a[0], b[0]], [a[2], b[2]], color="k", lw=1.8, solid_capstyle="round")
        ax.plot(c[0], c[2], "o", color="C0", ms=4)
        ax.axhline(0.0, color="0.4", lw=1)
        ax.set_xlim(x0, x1)
        ax.set_ylim(-0.1, max(2.0, float(np.max(com[:, 2])) + 0.8))
        ax.set_aspect("equal")
        ax.set_title(f"{label}, {t:.2f} s", fontsize=9)
        ax.set_xlabel("x (m)")
        ax.grid(alpha=0.3)
    np.atleast_1d(axs)[0].set_ylabel("z (m)")
    np.atleast_1d(axs)[0].legend(fontsize=7, loc="upper left")
    return _save(fig, path)
