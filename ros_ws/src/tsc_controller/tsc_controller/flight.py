"""The FLIGHT domain: :class:`Flight`."""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from . import outputs as O
from .config import ControllerConfig
from .domain_outputs import _mk
from .dynamics import SIDES, Dynamics
from .reference import Domain
from .profiles import quintic
from .tsc import Desired

MOTOR_HELD_PRE_T1 = tuple(f"{s}_{j}" for s in SIDES for j in ("hip_roll", "hip_yaw", "hip_pitch", "foot"))
MOTOR_HELD_MID = tuple(f"{s}_{j}" for s in SIDES for j in ("hip_roll", "hip_yaw", "foot"))
MOTOR_HELD_POST_T1 = tuple(f"{s}_{j}" for s in SIDES for j in ("hip_roll", "hip_yaw"))


class Flight:
    """FLIGHT: the flywheel's momentum (eq. Y^F_1) or, with a planned pelvis pitch, that pitch; per-leg
    length; before T1 the motor joints but the knees held at their lift-off values (and, in a
    somersault, the pelvis axis along world y; with ``flight_legs_preplaced`` the hip pitches give way
    to the leg angles from T1/2), after T1 the feet placed for the touch-down (leg angle, toe pitch)
    and the hips' roll and yaw held (eq. Y^F_2); in a somersault the two legs' hip pitch and knee held
    equal throughout (LegAsymmetry at 0)."""
    domain = Domain.FLIGHT

    def __init__(self, dyn: Dynamics, cfg: ControllerConfig, pitch):
        """``pitch``: the controller's unwrapped sagittal pelvis pitch, a callable."""
        self.dyn, self.cfg = dyn, cfg
        g = cfg.gains
        self.o_Hfw = _mk(O.FlywheelMomentum, "H_flywheel", g)
        self.o_pitch = _mk(O.SagittalPitch, "pitch", g, source=pitch)
        self.o_axis = _mk(O.PelvisAxisTilt, "axis", g)
        self._z2 = np.zeros(2)
        self.o_Lleg = [_mk(O.LegLength, f"L_{s}", g, "L_leg", sides=(s,)) for s in SIDES]
        self.o_beta = [_mk(O.LegAngle, f"beta_{s}", g, "beta_leg", sides=(s,)) for s in SIDES]
        self._beta_w0 = self.o_beta[0].weight
        self.o_toe = [_mk(O.FootPitch, f"toe_{s}", g, "toe_pitch", sides=(s,)) for s in SIDES]
        self.o_j_pre = _mk(O.JointPositions, "joints", g, joints=MOTOR_HELD_PRE_T1)
        self.o_j_post = _mk(O.JointPositions, "joints", g, joints=MOTOR_HELD_POST_T1)
        self.o_j_mid = _mk(O.JointPositions, "joints", g, joints=MOTOR_HELD_MID)
        self.o_sym = _mk(O.LegAsymmetry, "leg_symmetry", g)
        self._z_sym = np.zeros(self.o_sym.dim)
        self.state = None                # the lift-off posture and momentum (the first FLIGHT tick's)

    def enter(self):
        self.state = None

    def task(self, t, ref, t_enter, pitch, somersault, u_prev):
        """Outputs and desired values at t; ``pitch``: the unwrapped pelvis pitch now; ``u_prev``:
        the last command (its flywheel torque)."""
        dyn = self.dyn
        tau = t - t_enter + self.cfg.flight_lead
        if self.state is None:
            q_pre = self.o_j_pre.evaluate(dyn)[0]
            self.state = dict(
                H=self.o_Hfw.evaluate(dyn)[0], L=[o.evaluate(dyn)[0] for o in self.o_Lleg],
                q_pre=q_pre, q_post=self.o_j_post.evaluate(dyn)[0], q_mid=self.o_j_mid.evaluate(dyn)[0],
                beta=[o.evaluate(dyn)[0] for o in self.o_beta])
        f = self.state
        smp = ref.sample(tau) if ref is not None else {}
        if ref is not None and tau > ref.duration:
            # a touch-down later than planned: past its end the plan holds its last value at rest.  Its
            # last sample's acceleration is the pitch trapezoid's braking, which held on would spin the
            # flywheel up and turn the pelvis back until the touch-down
            smp = {name: (v, 0.0, 0.0) for name, (v, _dv, _ddv) in smp.items()}
        z = np.zeros(1)

        def d(name, default):
            if name in smp:
                v, dv, ddv = smp[name]
                return Desired(np.array([v]), np.array([dv]), np.array([ddv]))
            return Desired(np.asarray(default, float), z, z)
        T_f = None
        if ref is not None:
            T_f = ref.parameters.get("flight_time", ref.duration)
        T1 = ref.parameters.get("T1", self.cfg.t1_fraction * T_f) if ref is not None else np.inf
        if "H_flywheel" in smp:
            outs, des = [self.o_Hfw], [d("H_flywheel", None)]
        elif "phi_pitch" in smp and self.cfg.flight_pitch_output:
            outs, des = [self.o_pitch], [d("phi_pitch", None)]
        else:
            outs, des = [self.o_Hfw], [Desired(*self._momentum_transmission(smp, pitch), z)]
        outs = outs + self.o_Lleg
        des = des + [d("L", f["L"][k]) for k in range(2)]
        if somersault and self.o_sym.weight > 0.0:            # see config.DEFAULT_GAINS["leg_symmetry"]
            outs.append(self.o_sym)
            des.append(Desired(self._z_sym, self._z_sym, self._z_sym))
        bplus = ref.parameters.get("beta_liftoff") if ref is not None else None
        on_pelvis = "phi_pitch" in smp and self.cfg.flight_legs_on_pelvis
        preplace = (somersault and on_pelvis and bplus is not None and self.cfg.flight_legs_preplaced
                    and tau >= 0.5 * T1)
        if tau < T1:
            if somersault and self.o_axis.weight > 0.0:          # see config.DEFAULT_GAINS["axis"]
                outs.append(self.o_axis)
                des.append(Desired(self._z2, self._z2, self._z2))
            if preplace:
                outs += self.o_beta
                des += self._legs_preplaced(f, ref, tau, T1, pitch, -bplus)
                outs.append(self.o_j_mid)
                des.append(Desired(f["q_mid"], np.zeros(len(f["q_mid"])), np.zeros(len(f["q_mid"]))))
            else:
                outs.append(self.o_j_pre)
                des.append(Desired(f["q_pre"], np.zeros(len(f["q_pre"])), np.zeros(len(f["q_pre"]))))
        else:
            # the foot placement is a world leg angle for the pelvis at its final pitch theta_T; with
            # ``flight_legs_on_pelvis`` it is offset by (theta - theta_T) and its rates (see the config)
            off = np.zeros(3)
            if on_pelvis:
                off = np.array([pitch - self._final_pitch(f, ref), self._pelvis_pitch_rate(),
                                self._flywheel_pitch_acc(u_prev)])
            w_beta = self.cfg.somersault_beta_weight if somersault else self._beta_w0
            for k in range(2):
                b = -(bplus if bplus is not None else f["beta"][k][0])
                self.o_beta[k].weight = w_beta
                outs += [self.o_beta[k], self.o_toe[k]]
                bd = d("beta_leg", [b])
                des += [Desired(bd.value - off[0], bd.d_value - off[1], bd.dd_value - off[2]),
                        d("toe_pitch", [0.0])]
            outs.append(self.o_j_post)
            des.append(Desired(f["q_post"], np.zeros(len(f["q_post"])), np.zeros(len(f["q_post"]))))
        return outs, des

    def _final_pitch(self, f, ref):
        """theta_T, the pelvis pitch at the end of this flight reference (read once per reference)."""
        if f.get("ref") is not ref:
            f["ref"], f["th_T"] = ref, ref.sample(ref.duration)["phi_pitch"][0]
        return f["th_T"]

    def _flywheel_pitch_acc(self, u_prev):
        """Pelvis (with legs) pitch acceleration from the last flywheel torque (its reaction): without it
        the legs lag the pelvis's deceleration after T1 by ~0.45 rad (kp 100, kd 20 against ~80 rad/s^2)
        and land with the feet far ahead."""
        R = self.dyn.data.oMi[self.dyn.base_jid].rotation
        return -float(u_prev[-1]) * float(R[1] @ self.o_Hfw._a) / max(self._rest_inertia(), 1e-3)

    def _legs_preplaced(self, f, ref, tau, T1, pitch, b):
        """Leg angles over T1/2 .. T1 (``flight_legs_preplaced``): each leg's angle on the pelvis,
        beta + theta, goes min-jerk from its value at T1/2 to the touch-down's, b + theta_T (eq. Y^F_2's
        placement on the pelvis at its final pitch), so that after T1 the placement holds rather than
        swings the legs while the flywheel stops the body.  The pelvis's acceleration is the plan's:
        in the cruise the flywheel's torque goes into the tuck's extension, not into the pelvis."""
        th_T, w_p = self._final_pitch(f, ref), self._pelvis_pitch_rate()
        a_p = float(ref.sample(tau)["phi_pitch"][2])
        y = [float(o.evaluate(self.dyn)[0][0]) for o in self.o_beta]
        if f.get("mid") is None:
            f["mid"] = [yk + pitch for yk in y]
        out = []
        for k, o in enumerate(self.o_beta):
            o.weight = self.cfg.somersault_beta_weight
            rel0 = f["mid"][k]
            d_rel = (b + th_T - rel0 + np.pi) % (2.0 * np.pi) - np.pi
            v, dv, ddv = quintic(rel0, rel0 + d_rel, 0.5 * T1, tau - 0.5 * T1)
            target = float(v) - pitch
            target = y[k] + (target - y[k] + np.pi) % (2.0 * np.pi) - np.pi      # beta is an atan2
            out.append(Desired(np.array([target]), np.array([float(dv) - w_p]), np.array([float(ddv) - a_p])))
        return out

    def _rest_inertia(self):
        """Centroidal pitch inertia of the robot without the flywheel's spin inertia (sum_i I_i)."""
        dyn = self.dyn
        pin.ccrba(dyn.model, dyn.data, dyn.q, dyn.v)            # data.Ig: centroidal composite inertia
        return float(dyn.data.Ig.inertia[1, 1]) - self.o_Hfw._I

    def _momentum_transmission(self, smp, pitch):
        """Eq. (momentumTrans): H_fw^des = H_pitch - omega_cl * sum_i I_i with omega_cl = omega_des -
        k (theta_pelvis - theta_des), theta_des, omega_des, alpha_des from the reference's ``phi_pitch``
        (or 0: a level pelvis); and its rate, -(alpha_des - k (omega_pelvis - omega_des)) * sum_i I_i
        (H_pitch is conserved in flight; the change of sum_i I_i is left out).  Returns (value, rate)."""
        dyn = self.dyn
        H_pitch = float(dyn.Ag[4] @ dyn.v)
        th_des, om_des, al_des = (float(x) for x in smp.get("phi_pitch", (0.0, 0.0, 0.0)))
        k = self.cfg.k_theta
        I = self._rest_inertia()
        value = H_pitch - (om_des - k * (pitch - th_des)) * I
        rate = -(al_des - k * (self._pelvis_pitch_rate() - om_des)) * I
        return np.array([value]), np.array([rate])

    def _pelvis_pitch_rate(self):
        """World-y component of the pelvis's angular velocity (rad/s; the base velocity is local)."""
        dyn, b = self.dyn, self.o_Hfw._base_v
        return float(dyn.data.oMi[dyn.base_jid].rotation[1] @ dyn.v[b + 3:b + 6])
