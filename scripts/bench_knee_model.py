#!/usr/bin/env python3
"""The knees' torque in a flip's push against the planner's two knee models: offline (flip_tools.offline),
every 5 ms of JUMPING, the measured sum of the knee motor torques against the one the foot force asks
of them by virtual work, (F_r + rho(L) f_t) dL/dq_knee ("axial + tangential", FSLIPParams.knee_tangential)
and F_r dL/dq_knee ("axial", the default).  The foot force is the total GRF from the COM's acceleration,
split along and across the COM-feet line; L is the hip-foot length.  Prints the samples and, over those
with the knees below their limit, the least-squares share of each model's terms and each model's error.

    .venv/bin/python scripts/bench_knee_model.py [--flip C|B|F] [--start 0.7] [--knee-tangential]
"""
from __future__ import annotations

import argparse
import math

import numpy as np

FLIPS = {"B": ("backflip", dict(apex_height=1.3), 0.0),
         "F": ("frontflip", dict(apex_height=1.3), 0.0),
         "C": ("frontflip", dict(apex_height=1.2, forward_distance=0.6, platform_height=0.5), 0.5)}


def samples(flip: str, start: float, knee_tangential: bool) -> np.ndarray:
    """Rows (t, L, F_r, f_t, measured knee torque sum, axial model, axial + tangential model)."""
    import mujoco
    from cassie_flip_sim.simulator import Simulator
    from cassie_model.model import Scenario, export_mjcf
    from cassie_model.robot_params import MOTOR_NAMES
    from flip_tools import offline as of
    from fslip_planner import fslip as F
    from tsc_controller import Controller
    kind, request, platform = FLIPS[flip]
    sim = Simulator(scenario=Scenario.platform(platform) if platform else Scenario.flat(),
                    motor_speed_scale=3.0, flywheel_torque=260.0)
    ctl = Controller(export_mjcf(sim.flywheel), motor_speed_scale=3.0, flywheel_torque=260.0)
    p = F.params_for("I", motor_speed_scale=3.0, flywheel_torque=260.0)
    jid = [mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_JOINT, f"{s}_{j}")
           for s in ("left", "right") for j in ("hip_pitch", "foot")]
    knees = [MOTOR_NAMES.index("left_knee"), MOTOR_NAMES.index("right_knee")]
    rows, prev = [], {}

    def on_step(sim, ctl, u, info):
        if info["domain"] != 1:                    # JUMPING
            return
        v, t = sim.com_velocity(), sim.time
        if "v" in prev and sim.step_index % 10 == 0:
            grf = sim.total_mass() * ((v - prev["v"]) / (t - prev["t"]) + np.array([0.0, 0.0, p.g]))
            d = sim.com_position() - sim.support_center()
            r = math.hypot(d[0], d[2])
            sb, cb = d[0] / r, d[2] / r
            F_r, f_t = grf[0] * sb + grf[2] * cb, -grf[0] * cb + grf[2] * sb   # as fslip.grf splits it
            xa = sim.data.xanchor
            L = float(np.mean([np.linalg.norm(xa[jid[i + 1]] - xa[jid[i]]) for i in (0, 2)]))
            dL_dq = 1.0 / float(p.dqknee_dL(L))
            rows.append((t, L, F_r, f_t, float(u[knees[0]] + u[knees[1]]), F_r * dL_dq,
                         (F_r + float(p.reg("rho", L)) * f_t) * dL_dq))
        if sim.step_index % 10 == 9:
            prev.update(v=v.copy(), t=t)

    of.run(kind, seconds=start + 1.3, start=start, sim=sim, controller=ctl, every=20, on_step=on_step,
           motor_speed_scale=3.0, flywheel_torque=260.0, knee_tangential=knee_tangential, **request)
    return np.array(rows)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--flip", choices=list(FLIPS), default="C")
    ap.add_argument("--start", type=float, default=0.7)
    ap.add_argument("--knee-tangential", action="store_true", help="the flip planned with that knee model")
    a = ap.parse_args()
    from fslip_planner.regression import knee_torque_limit
    rows = samples(a.flip, a.start, a.knee_tangential)
    print(f"flip {a.flip} from {a.start} s, planned with the {'axial + tangential' if a.knee_tangential else 'axial'}"
          " knee model (somersault robot: leg motors x3, 260 N*m flywheel)")
    print("| t s | L m | F_r N | f_t N | knees measured N*m | axial model | axial + tangential |")
    print("|---|---|---|---|---|---|---|")
    for r in rows[::2]:
        print("| %.3f | %.3f | %.0f | %.0f | %.1f | %.1f | %.1f |" % tuple(r))
    free = np.abs(rows[:, 4]) < 2 * knee_torque_limit() - 5.0          # the knees below their limit
    X = np.c_[rows[free, 5], rows[free, 6] - rows[free, 5]]
    share, *_ = np.linalg.lstsq(X, rows[free, 4], rcond=None)
    print(f"over {int(free.sum())} samples below the knees' limit: measured = {share[0]:.2f} axial "
          f"+ {share[1]:.2f} tangential term (least squares)")
    for name, col in (("axial", 5), ("axial + tangential", 6)):
        e = rows[free, 4] - rows[free, col]
        print(f"  {name} model: error rms {np.sqrt(np.mean(e ** 2)):.1f} N*m, mean {e.mean():.1f} N*m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
