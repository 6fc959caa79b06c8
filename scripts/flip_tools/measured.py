"""The paper's outputs as the robot actually had them, recomputed from a bag: /joint_states and
/odom (same stamps) through the model on /robot_description_mjcf, with the controller's own output
definitions (tsc_controller.outputs: centroidal pitch momentum, leg length, COM, flywheel
momentum).  For plots of planned vs. measured; the landing verdict does not use it (it reads /odom
only)."""
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


def measured_outputs(data: BagData, every_s: float = 0.005) -> dict | None:
    """{"t", "H_pitch", "L", "x_com", "H_flywheel"} sampled every ``every_s`` of sim time, or None
    when the bag lacks the state or a model of this robot."""
    cache = data.__dict__.setdefault("_measured_outputs", {})    # summary and plots both ask
    if every_s not in cache:
        cache[every_s] = _measured_outputs(data, every_s)
    return cache[every_s]


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
