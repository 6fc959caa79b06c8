"""The paper's outputs as the robot actually had them, recomputed from a bag: /joint_states and
/odom (same stamps) through the model on /robot_description_mjcf, with the controller's own output
definitions (tsc_controller.outputs: centroidal pitch momentum, leg length, COM, flywheel
momentum); and the feet's wrench topics in world axes, through the URDF on /robot_description as
/tf gives it.  For plots of planned vs. measured; the landing verdict does not use it (it reads
/odom only)."""
from __future__ import annotations

import numpy as np

from .bag import BagData


def _last_text(data: BagData, topic: str) -> str:
    msg = data.get(topic) or {}
    text = msg.get("data")
    return (text[-1] if isinstance(text, list) and text else text) or ""


def bag_mjcf(data: BagData) -> str:
    """The MJCF the controller was built from: /robot_description_mjcf, or /robot_description in
    bags from before the URDF took that topic (an MJCF there starts with ``<mujoco``)."""
    mjcf = _last_text(data, "/robot_description_mjcf")
    if mjcf:
        return mjcf
    old = _last_text(data, "/robot_description")
    return old if old.lstrip().startswith("<mujoco") else ""


def robot_mass(data: BagData) -> float | None:
    """Total mass (kg) of the bag's robot (its MJCF, through MuJoCo), or None."""
    mjcf = bag_mjcf(data)
    if not mjcf:
        return None
    import mujoco
    try:
        return float(mujoco.mj_getTotalmass(mujoco.MjModel.from_xml_string(mjcf)))
    except Exception:  # noqa: BLE001 - a description that is not a whole model (a stand-in's)
        return None


def measured_outputs(data: BagData, every_s: float = 0.005) -> dict | None:
    """{"t", "H_pitch", "L", "x_com", "H_flywheel"} sampled every ``every_s`` of sim time, or None
    when the bag lacks the state or a model of this robot."""
    key = ("measured_outputs", every_s)                           # summary and plots both ask
    if key not in data.derived:
        data.derived[key] = _measured_outputs(data, every_s)
    return data.derived[key]


def _measured_outputs(data: BagData, every_s: float) -> dict | None:
    mjcf, js, od = bag_mjcf(data), data.get("/joint_states"), data.get("/odom")
    if not mjcf or js is None or od is None or not len(js["t"]) or not len(od["t"]):
        return None
    from tsc_controller import outputs as O
    from tsc_controller.dynamics import Dynamics
    from tsc_controller.state import StateConverter
    try:
        dyn = Dynamics(mjcf)
        conv = StateConverter(dyn)
    except Exception:  # noqa: BLE001 - a description that is not this robot's (e.g. a stand-in's)
        return None
    outs = {"H_pitch": O.CentroidalPitchMomentum("H_pitch"), "L": O.LegLength("L"),
            "x_com": O.ComPosition("com", axes=(0, 1)), "H_flywheel": O.FlywheelMomentum("H_flywheel")}
    od_index = {round(float(t), 6): i for i, t in enumerate(od["t"])}
    res = {k: [] for k in ("t", *outs)}
    next_t = -np.inf
    for i, t in enumerate(js["t"]):
        if t < next_t:
            continue
        j = od_index.get(round(float(t), 6))
        if j is None or np.isnan(js["pos"][i]).any():
            continue
        next_t = t + every_s
        q, v = conv.from_ros(js["names"], js["pos"][i], js["vel"][i], od["pos"][j],
                             od["quat"][j], od["lin"][j], od["ang"][j])
        dyn.update(q, v)
        res["t"].append(float(t))
        for k, o in outs.items():
            res[k].append(float(o.evaluate(dyn)[0][0]))
    return {k: np.asarray(v) for k, v in res.items()} if res["t"] else None


def foot_wrenches_world(data: BagData) -> dict | None:
    """The feet's wrenches (``/left_foot/wrench``, ``/right_foot/wrench``: each in its foot link's
    frame about its origin) in world axes, at the stamps both carry: each rotated by its link's pose
    at the /joint_states and /odom of that stamp, through the bag's URDF (/robot_description;
    cassie_flip_sim.link_transforms, the math of /tf).  {"t" (n,), "force" (n, 2, 3), "torque"
    (n, 2, 3) about each foot's origin, "origin" (n, 2, 3)}, feet in the order left, right; None
    when the bag lacks a topic, the URDF or the state."""
    from cassie_flip_sim.foot_wrench import FOOT_LINKS, WRENCH_TOPICS
    from cassie_flip_sim.link_transforms import LinkTransforms, link_poses
    ws = [data.get(t) for t in WRENCH_TOPICS]
    urdf, js, od = _last_text(data, "/robot_description"), data.get("/joint_states"), data.get("/odom")
    if any(w is None for w in ws) or not urdf.lstrip().startswith("<") or "<robot" not in urdf \
            or js is None or od is None:
        return None
    lt = LinkTransforms(urdf)
    key = lambda t: int(round(float(t) * 1e9))
    js_i = {key(t): i for i, t in enumerate(js["t"])}
    od_i = {key(t): i for i, t in enumerate(od["t"])}
    right = {key(t): i for i, t in enumerate(ws[1]["t"])}
    edges = None
    res = {"t": [], "force": [], "torque": [], "origin": []}
    for i, t in enumerate(ws[0]["t"]):
        k = key(t)
        j, o, r = js_i.get(k), od_i.get(k), right.get(k)
        if j is None or o is None or r is None or np.isnan(js["pos"][j]).any():
            continue
        lt.set_positions(js["names"], js["pos"][j])
        if edges is None:
            edges = lt.fixed
        poses = link_poses(lt.root, np.r_[od["pos"][o], od["quat"][o]], lt.moving() + edges)
        T = [poses[link] for link in FOOT_LINKS]
        res["t"].append(float(t))
        res["force"].append([T[0][:3, :3] @ ws[0]["force"][i], T[1][:3, :3] @ ws[1]["force"][r]])
        res["torque"].append([T[0][:3, :3] @ ws[0]["torque"][i], T[1][:3, :3] @ ws[1]["torque"][r]])
        res["origin"].append([T[0][:3, 3], T[1][:3, 3]])
    return {k: np.asarray(v) for k, v in res.items()} if res["t"] else None
