"""A video of a run rendered from its bag (/joint_states + /odom: what the simulator published), with
cassie_flip_sim.render (MuJoCo offscreen, EGL): DIR/flip.mp4 with ffmpeg on PATH, else DIR/flip.gif."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .bag import load_bag


def frame_rows(js: dict, od: dict, fps: float = 30.0) -> list[tuple[int, int]]:
    """(/joint_states row, /odom row) of each frame at ``fps`` of sim time: the first step with both
    at or after each frame's time."""
    od_t = {round(float(t), 6): i for i, t in enumerate(od["t"])}
    rows, next_t = [], -np.inf
    for i, t in enumerate(js["t"]):
        j = od_t.get(round(float(t), 6))
        if t < next_t or j is None:
            continue
        next_t = t + 1.0 / fps
        rows.append((i, j))
    return rows


def qpos_from_bag(model, js: dict, od: dict, fps: float = 30.0) -> list[np.ndarray]:
    """MuJoCo qpos sequences at ``fps`` of sim time (:func:`frame_rows`): free joint from /odom
    (position, quaternion), hinges from /joint_states by name, ball joints from their ``_x/_y/_z``
    rotation vectors."""
    import mujoco
    col = {n: i for i, n in enumerate(js["names"])}
    out = []
    for i, j in frame_rows(js, od, fps):
        q = model.qpos0.copy()
        for k in range(model.njnt):
            a, typ = model.jnt_qposadr[k], model.jnt_type[k]
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, k)
            if typ == mujoco.mjtJoint.mjJNT_FREE:
                x, y, z, w = od["quat"][j]
                q[a:a + 3] = od["pos"][j]
                q[a + 3:a + 7] = (w, x, y, z)
            elif typ == mujoco.mjtJoint.mjJNT_BALL:
                rv = np.array([js["pos"][i][col[f"{name}_{c}"]] for c in "xyz"])
                ang = float(np.linalg.norm(rv))
                quat = np.zeros(4)
                mujoco.mju_axisAngle2Quat(quat, rv / ang if ang > 0 else np.array([1.0, 0, 0]), ang)
                q[a:a + 4] = quat
            elif name in col:
                q[a] = js["pos"][i][col[name]]
        out.append(q)
    return out


def render_run(out_dir: str | Path, flywheel="I", scenario=None, fps: float = 30.0) -> Path:
    """Render DIR/bag to DIR/flip.mp4 (or .gif); returns the file written."""
    from cassie_model.model import build_model
    from cassie_flip_sim.render import render_states
    out_dir = Path(out_dir)
    data = load_bag(out_dir / "bag", ["/joint_states", "/odom"])
    model = build_model(flywheel, scenario)
    frames = qpos_from_bag(model, data["/joint_states"], data["/odom"], fps)
    if not frames:
        raise ValueError(f"{out_dir / 'bag'} holds no /joint_states with matching /odom to render")
    return render_states(model, frames, out_dir / "flip.mp4", fps=fps)
