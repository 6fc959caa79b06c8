"""Offscreen rendering of a sequence of MuJoCo states to GIF (Pillow) or MP4 (ffmpeg, if on PATH).

Uses ``mujoco.Renderer`` with EGL (headless; Debian: libegl1 + Mesa, which libegl1/libgl1 pull
in).  ``MUJOCO_GL`` defaults to ``egl`` when this module is imported before mujoco; if mujoco was
already imported with the default (GLFW) backend and there is no display, EGL is switched in.
"""
from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path
from typing import Iterable, List, Optional, Sequence, Union

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402


def _ensure_headless_gl() -> None:
    try:
        from mujoco.rendering.classic import gl_context
    except ImportError:        # older layout
        from mujoco import gl_context
    cls = getattr(gl_context, "GLContext", None)
    if cls is None or ("glfw" in getattr(cls, "__module__", "") and not os.environ.get("DISPLAY")):
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
        from mujoco.egl import GLContext
        gl_context.GLContext = GLContext


def render_frames(model: mujoco.MjModel, qpos_seq: Iterable[np.ndarray], *, width: int = 640,
                  height: int = 360, camera: Union[str, int, mujoco.MjvCamera] = "track",
                  track_body: str = "pelvis", distance: float = 3.0) -> List[np.ndarray]:
    """RGB frames (H, W, 3 uint8) of the given qpos sequence.

    camera="track": a free camera following ``track_body`` from the robot's left side (+y looks
    at the sagittal plane); a camera name or id of the model; or an MjvCamera."""
    _ensure_headless_gl()
    data = mujoco.MjData(model)
    frames = []
    cam = camera
    if camera == "track":
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        cam.trackbodyid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, track_body)
        cam.distance, cam.azimuth, cam.elevation = distance, 90.0, -10.0
    with mujoco.Renderer(model, height, width) as r:
        for q in qpos_seq:
            data.qpos[:] = q
            mujoco.mj_forward(model, data)
            r.update_scene(data, camera=cam)
            frames.append(r.render().copy())
    return frames


def save_animation(frames: Sequence[np.ndarray], path: Union[str, Path], fps: float = 30.0) -> Path:
    """Write frames to ``path``: ``.gif`` with Pillow, ``.mp4`` with ffmpeg (falls back to a GIF
    next to it when ffmpeg is missing).  Returns the path written."""
    path = Path(path)
    if path.suffix.lower() == ".mp4":
        ffmpeg = shutil.which("ffmpeg")
        if ffmpeg is not None:
            h, w = frames[0].shape[:2]
            cmd = [ffmpeg, "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24",
                   "-s", f"{w}x{h}", "-r", str(fps), "-i", "-", "-pix_fmt", "yuv420p",
                   "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", str(path)]
            subprocess.run(cmd, input=b"".join(np.ascontiguousarray(f).tobytes() for f in frames), check=True)
            return path
        path = path.with_suffix(".gif")
    from PIL import Image
    imgs = [Image.fromarray(f) for f in frames]
    imgs[0].save(path, save_all=True, append_images=imgs[1:], duration=int(round(1000.0 / fps)), loop=0)
    return path


def render_states(model: mujoco.MjModel, qpos_seq: Iterable[np.ndarray], path: Union[str, Path], *,
                  fps: float = 30.0, width: int = 640, height: int = 360,
                  camera: Union[str, int, mujoco.MjvCamera] = "track") -> Path:
    """Render a qpos sequence (already subsampled to ``fps``) to a GIF/MP4 file."""
    return save_animation(render_frames(model, qpos_seq, width=width, height=height, camera=camera), path, fps)


def subsample(qpos_log: Sequence[np.ndarray], timestep: float, fps: float = 30.0) -> List[np.ndarray]:
    """Every n-th state of a per-step log so that the result plays at ``fps`` in real time."""
    n = max(1, int(round(1.0 / (fps * timestep))))
    return list(qpos_log[::n])
