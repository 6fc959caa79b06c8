"""The standing targets, the feet's contact and the swing outputs the ground domains (STANDING,
JUMPING, LANDING) share: :class:`GroundTargets`."""
from __future__ import annotations

import math

import numpy as np

from . import outputs as O
from .config import ControllerConfig
from .domain_outputs import _mk
from .dynamics import SIDES, Dynamics
from .profiles import LEG_RISE_TIME, leg_catch, leg_catch_duration, quintic
from .tsc import Desired

#: (ground target, index in it, reference name): the targets a JUMPING or LANDING reference sets
_REFERENCE_TARGETS = (("H_pitch", 0, "H_pitch"), ("L", 0, "L"), ("com", 0, "x_com"), ("com", 1, "y_com"),
                      ("pelvis", 0, "phi_roll"), ("pelvis", 1, "phi_pitch"), ("pelvis", 2, "phi_yaw"))


class GroundTargets:
    """What the ground domains (STANDING, JUMPING, LANDING) share: the standing targets (the state at a
    domain's entry blended to the standing pose, the pitch momentum's removal, the landing's leg
    catch), the feet's contact and anchors, and the swing outputs of a foot off the ground.  In Python,
    or compiled (``compiled``: _native.GroundTargets, ControllerConfig.compiled_targets), which gives
    the same numbers to the bit (tests/unit/test_tsc_native.py).

    ``outputs`` (H_pitch, L, com, pelvis with the default gains) measure the state the targets start
    from; LANDING tracks a landing reference with them.  JUMPING continues the targets STANDING began
    (``reanchor`` only on entering STANDING or LANDING)."""

    def __init__(self, dyn: Dynamics, cfg: ControllerConfig, outputs):
        self.dyn, self.cfg = dyn, cfg
        self.outputs = outputs
        self.o_H, self.o_L, self.o_com, self.o_pel = outputs
        g = cfg.gains
        self.o_swing = [_mk(O.FootPoints, f"swing_{s}", g, "swing", side=s) for s in SIDES]
        # per-foot contact state in the ground domains, and per foot the toe, heel world positions where
        # it stands (the Python targets'; the compiled ones keep theirs: compiled.contact, .anchor(k))
        self.feet_contact = [True, True]
        self.foot_anchor = None
        # point-table rows of toe, heel of each foot
        self._feet_rows = np.array([dyn.point_index(f"{s}_{e}") for s in SIDES for e in ("toe", "heel")])
        # the shin springs (first and third leaf spring): q rows, stiffness, rest angle
        self._shin_q = dyn.spring_q[[0, 2]]
        self._shin_k, self._shin_q0 = dyn.spring_k[[0, 2]], dyn.q_spring[self._shin_q]
        self._shin_k_list, self._shin_q0_list = self._shin_k.tolist(), self._shin_q0.tolist()
        self.z_ground = None
        self.stand = None                # the targets' anchors at the domain's entry (see targets)
        self.compiled = self._des = None
        if cfg.backend == "native" and cfg.compiled_targets:
            self._compile()

    def _compile(self):
        """The targets in C++ (_native.GroundTargets) and the Desired objects that hold views of its
        buffers (rewritten by every tick)."""
        from . import _native
        cfg, pi = self.cfg, self.dyn.point_index
        self.compiled = _native.GroundTargets(
            feet=self._feet_rows.tolist(), legs=[pi(f"{s}_{p}") for s in SIDES for p in ("foot", "hip")],
            shin_q=self._shin_q.tolist(), shin_k=self._shin_k_list, shin_q0=self._shin_q0_list,
            mass=self.dyn.mass,
            cfg=dict(per_foot_contact=bool(cfg.per_foot_contact), foot_lift=cfg.foot_lift, foot_land=cfg.foot_land,
                     foot_loaded_spring=cfg.foot_loaded_spring, kp=self.o_H.kp,
                     landing_moment=cfg.landing_moment, landing_moment_late=cfg.landing_moment_late or 0.0,
                     landing_late_after=cfg.landing_late_after, moment_ramp=cfg.moment_ramp,
                     com_shift=cfg.com_shift, catch_decel=cfg.catch_decel, L_min=cfg.L_min,
                     catch_slack=cfg.catch_slack, rise_time=LEG_RISE_TIME, rise_time2=LEG_RISE_TIME ** 2))
        b = self.compiled.buffers()
        self._des = {k: Desired(*b[k]) for k in ("H_pitch", "L", "com", "pelvis")}

    def reanchor(self):
        """Start the targets again from the state at the next tick (entering STANDING or LANDING)."""
        self.stand = None

    def turn(self, psi, pivot):
        """The targets' anchors in the frame turned by -``psi`` about the vertical through ``pivot``
        (x, y): COM positions and velocity turned, pelvis yaw less ``psi`` (Controller._heading_frame)."""
        s = self.stand
        if s is None:
            return
        c, sn = math.cos(psi), math.sin(psi)
        R = np.array([[c, sn], [-sn, c]])
        pivot = np.asarray(pivot, float)
        for k in ("c0", "c1"):
            s[k][:2] = pivot + R @ (s[k][:2] - pivot)
        s["cd0"][:2] = R @ s["cd0"][:2]
        for k in ("p0", "p1"):
            s[k][2] -= psi
        if self.compiled is not None:         # the same entry, its anchors turned
            T = self.cfg.blend_time
            self.compiled.begin(s["t0"], float(s["L0"][0]), float(s["Ld0"][0]), float(s["L1"][0]), s["c0"], s["cd0"],
                                s["c1"], s["p0"], s["pd0"], s["p1"], T, T ** 2)

    def H_now(self):
        """The pitch momentum the targets' removal last saw (0 before their first tick)."""
        if self.compiled is not None:
            return self.compiled.H_now
        return self.stand.get("H_now", 0.0)

    def landing_done(self, t):
        """The own landing is over: its profiles have ended (leg catch + rise, momentum removal) and
        the momentum is out (``landing_H_done``)."""
        return (self.stand is not None and t - self.stand["t0"] > self.stand["T_done"]
                and abs(self.H_now()) <= self.cfg.landing_H_done)

    # -------------------------------------------------------------- targets
    def feet(self):
        dyn = self.dyn
        pts = [dyn.point(f"{s}_{k}")[0] for s in SIDES for k in ("toe", "heel")]
        mid = np.mean(pts, axis=0)
        head = [dyn.foot_frame(s)[0] for s in SIDES]
        h = head[0] + head[1]
        return mid, float(np.arctan2(h[1], h[0]))

    def targets(self, t, landing):
        """{output name: Desired} of the ground outputs at t; ``landing``: the domain is LANDING (the
        COM target moves against the removal's CoP offset, the leg catch re-anchors)."""
        dyn = self.dyn
        if self.stand is None:
            mid, yaw = self.feet()
            L0, _, _, Ld0 = self.o_L.evaluate(dyn)
            # At touch-down the leg has not started to shorten yet (the feet moved with the body until
            # the impact); once the feet stop, it shortens at the body's sink rate: catch that.
            Ld0 = np.minimum(Ld0, dyn.hg_lin[2] / dyn.mass)
            if self.cfg.L_stand is None:
                self.cfg.L_stand = float(L0[0])
            c0, _, _, cd0 = self.o_com.evaluate(dyn)
            p0, _, _, pd0 = self.o_pel.evaluate(dyn)
            # start from the current value and velocity (soft catch after touch-down)
            H0 = self.o_H.evaluate(dyn)[0]
            if landing and self.cfg.landing_yaw_stop is not None:
                yaw = float(p0[2] + 0.5 * pd0[2] * self.cfg.landing_yaw_stop)    # see the config's field
            self.stand = dict(t0=t, L0=L0.copy(), c0=c0.copy(), p0=p0.copy(), L1=np.array([self.cfg.L_stand]),
                              c1=mid[:2].copy(), p1=np.array([0.0, 0.0, yaw]),
                              Ld0=Ld0.copy(), cd0=cd0.copy(), pd0=pd0.copy(), H0=H0.copy(),
                              TH=max(self.cfg.blend_time, abs(float(H0[0])) / self.cfg.landing_moment))
            self.stand["T_done"] = max(self.cfg.blend_time, self.stand["TH"],
                                       leg_catch_duration(float(L0[0]), float(Ld0[0]), self.cfg.catch_decel,
                                                          self.cfg.L_min))
            if self.compiled is not None:
                s, T = self.stand, self.cfg.blend_time
                self.compiled.begin(t, float(s["L0"][0]), float(s["Ld0"][0]), float(s["L1"][0]), s["c0"], s["cd0"],
                                    s["c1"], s["p0"], s["pd0"], s["p1"], T, T ** 2)
        if self.compiled is not None:
            self.compiled.tick(dyn.native, t, landing)
            return self._des
        s = self.stand
        T, dt = self.cfg.blend_time, t - s["t0"]
        H = self._momentum_removal(dt)
        com = [np.array(x, float) for x in quintic(s["c0"], s["c1"], T, dt, s["cd0"])]
        # That moment comes from the centre of pressure offset from the COM, dH/dt = -(x_cop - x_com) m g:
        # the COM is moved the other way by com_shift of that offset, so that the centre of pressure
        # stays inside the feet (with the COM over the middle of the feet the moment needs the centre
        # of pressure near toe or heel, and a COM target that fights it makes the QP take the moment
        # from horizontal forces instead, which drive the COM off the feet).
        # (LANDING only: in STANDING the feedback on the momentum's wiggles would move the COM target
        # about: 1.5 cm height drift in 5 s of standing)
        k = self.cfg.com_shift / (self.dyn.mass * 9.81) if landing else 0.0
        com[0][0] += k * float(H[1][0])
        com[1][0] += k * float(H[2][0])
        if self.foot_anchor is not None:
            # the feet creep on the ground during a hard landing: the COM follows where they stand now
            # (docs/tuning.md, Ground targets)
            a = self.foot_anchor
            mid = 0.25 * (a[0][:2] + a[0][3:5] + a[1][:2] + a[1][3:5])
            com[0][:2] += mid - s["c1"][:2]
        L_des = self._leg_catch(t, landing)
        return {
            "H_pitch": Desired(*H),
            "L": Desired(*L_des),
            "com": Desired(*com),
            "pelvis": Desired(*quintic(s["p0"], s["p1"], T, dt, s["pd0"])),
        }

    def follow(self, des, smp):
        """Set the targets a reference sample ``smp`` names (_REFERENCE_TARGETS) to its values; the
        others keep the standing targets'."""
        for key, idx, name in _REFERENCE_TARGETS:
            if name in smp:
                v, dv, ddv = smp[name]
                d = des[key]
                if self.compiled is None:     # (the compiled targets' buffers are rewritten every tick)
                    d.value = np.array(d.value, float)
                    d.d_value = np.array(d.d_value, float)
                    d.dd_value = np.array(d.dd_value, float)
                d.value[idx], d.d_value[idx], d.dd_value[idx] = v, dv, ddv

    def _leg_catch(self, t, landing):
        """Leg length of the landing (:func:`leg_catch` from the leg and sink rate at touch-down),
        re-anchored on the measured state whenever the body sinks slower than the profile shortens
        the leg by more than ``catch_slack``: the touch-down impact takes a good part of the sink
        rate at once, and a leg still shortened at the profile's rate pulls the feet off the ground
        (docs/tuning.md, Ground targets)."""
        s, cfg = self.stand, self.cfg
        tL = s.get("tL", s["t0"])
        des = leg_catch(float(s["L0"][0]), float(s["Ld0"][0]), float(s["L1"][0]), t - tL, cfg.catch_decel, cfg.L_min)
        vz = float(self.dyn.hg_lin[2]) / self.dyn.mass
        if landing and vz < 0.0 and float(des[1][0]) < vz - cfg.catch_slack:
            s["L0"] = self.o_L.evaluate(self.dyn)[0].copy()
            s["Ld0"], s["tL"] = np.array([vz]), t
            des = leg_catch(float(s["L0"][0]), vz, float(s["L1"][0]), 0.0, cfg.catch_decel, cfg.L_min)
        return des

    def _momentum_removal(self, dt):
        """Desired (H, dH/dt, d2H/dt2) of the pitch momentum a landing brings (the flywheel's, after a
        flip): taken out at a moment the feet can give, dH/dt = -clip(kp H, +-M), M = ``landing_moment``
        ramped in over ``moment_ramp``, from the measured H (value = H: no error to correct), not a
        time profile, which the impact puts the landing behind (docs/tuning.md, Ground targets)."""
        kp = self.o_H.kp
        H_now = float(self.o_H.evaluate(self.dyn)[0][0])
        self.stand["H_now"] = H_now
        cfg = self.cfg
        # M ramps from 0 to landing_moment over moment_ramp, later from there to landing_moment_late
        M0, M1, t1 = 0.0, cfg.landing_moment, 0.0
        if cfg.landing_moment_late and dt > cfg.landing_late_after:
            M0, M1, t1 = cfg.landing_moment, cfg.landing_moment_late, cfg.landing_late_after
        x = (dt - t1) / cfg.moment_ramp if cfg.moment_ramp > 0 else 1.0
        M = M0 + (M1 - M0) * min(1.0, max(x, 0.0))
        slope = (M1 - M0) / cfg.moment_ramp if x < 1.0 else 0.0
        if kp * abs(H_now) >= M:
            hd = -math.copysign(M, H_now)
            hdd = -math.copysign(slope, H_now)
        else:
            hd, hdd = -kp * H_now, 0.0
        return np.array([H_now]), np.array([hd]), np.array([hdd])

    def standing_H_weight(self, w0):
        """STANDING's H_pitch weight (see :meth:`Standing.H_weight`) for its standing value ``w0``."""
        cfg = self.cfg
        if self.compiled is not None:         # the same, compiled, on the compiled targets' feet
            return self.compiled.standing_H_weight(self.dyn.native, w0, cfg.standing_H_edge,
                                                   cfg.standing_H_edge_weight)
        if cfg.standing_H_edge <= 0.0 or self.foot_anchor is None:
            return w0
        dyn = self.dyn
        feet = [k for k in range(2) if self.feet_contact[k]] or [0, 1]
        a = self.foot_anchor
        # heading of the feet (toe - heel, horizontal, summed over both) and the feet's span along it
        hx = sum(float(a[k][0] - a[k][3]) for k in range(2))
        hy = sum(float(a[k][1] - a[k][4]) for k in range(2))
        n = math.hypot(hx, hy)
        if n < 1e-6:
            return w0
        hx, hy = hx / n, hy / n
        front = max(hx * float(a[k][0]) + hy * float(a[k][1]) for k in feet)
        back = min(hx * float(a[k][3]) + hy * float(a[k][4]) for k in feet)
        c = dyn.com
        xi = hx * float(c[0]) + hy * float(c[1])
        outside = max(xi - front, back - xi)
        f = min(1.0, max(1.0 - outside / cfg.standing_H_edge, 0.0))
        return w0 * (cfg.standing_H_edge_weight + (1.0 - cfg.standing_H_edge_weight) * f)

    # -------------------------------------------------------------- feet
    def update_feet(self):
        """Per-foot contact (LANDING, STANDING) from the kinematics and the shin springs: a foot whose
        lower end is ``foot_lift`` above the ground (lowest foot point when the domain began, then
        following the loaded feet), and whose leg's shin
        spring carries less than ``foot_loaded_spring``, is off it; back on it below ``foot_land``.  A foot on the ground keeps its anchor (toe, heel positions, at ground height);
        an airborne foot keeps the last one as its swing target.  The QP's flat-foot contact for a foot
        that has unloaded and lifted is a model of something that is not there: torques computed
        for it throw the foot about (docs/tuning.md, Ground targets)."""
        if self.compiled is not None:
            self.compiled.update_feet(self.dyn.native)
            return
        dyn, cfg = self.dyn, self.cfg
        # per foot: toe, heel (a copy: its rows are the anchors, never written); the arithmetic below
        # in Python floats, the same operations as numpy's element-wise ones (a tick's ~10 numpy calls
        # on 2-element arrays were most of this method's time)
        P = dyn.P[self._feet_rows].reshape(2, 6)
        z_low = [min(p[2], p[5]) for p in P.tolist()]               # lowest point of each foot
        if self.foot_anchor is None:
            self.z_ground = min(z_low)
            self.foot_anchor = [P[0], P[1]]
            self.feet_contact = [True, True]
        # shin leaf-spring torque of each leg (about 29 N*m standing): a leg that still carries load is
        # on the ground whatever the kinematics say (a crouched foot rolled onto its toe carries it)
        tau_shin = [-k * (q - q0) for k, q, q0 in zip(self._shin_k_list, dyn.q[self._shin_q].tolist(),
                                                      self._shin_q0_list)]
        for k, p in enumerate(P):
            # a foot rocked onto its toe or heel keeps its contact rows: declared off, its swing output
            # could not bring it down (it rests on one end) and the robot stood on the other leg
            h = z_low[k] - self.z_ground
            if self.feet_contact[k]:
                if cfg.per_foot_contact and h > cfg.foot_lift and tau_shin[k] < cfg.foot_loaded_spring:
                    self.feet_contact[k] = False
                else:
                    self.foot_anchor[k] = p
                    if tau_shin[k] >= cfg.foot_loaded_spring:
                        # the ground height follows the loaded feet (first estimate, at touch-down, is
                        # a few mm low: the impact pushes the feet into the compliant contact)
                        self.z_ground += 0.01 * (z_low[k] - self.z_ground)
            elif h < cfg.foot_land:
                self.feet_contact[k] = True

    def reset_feet(self):
        """Both feet on the ground, no anchors (JUMPING: the feet leave the ground on purpose at the end
        of the push-off; FLIGHT)."""
        if self.compiled is not None:
            self.compiled.reset_feet()
        else:
            self.foot_anchor = None
            self.z_ground = None
            self.feet_contact = [True, True]

    def swing(self, outs, des):
        """Add the swing output of each foot off the ground (only while the other one is on it)."""
        g = self.compiled
        contact = self.feet_contact if g is None else g.contact
        if all(contact) or not any(contact):
            return outs, des, (True, True)
        outs, des = list(outs), list(des)
        for k in range(2):
            if not contact[k]:
                a = self.foot_anchor[k].copy() if g is None else g.anchor(k)
                # back down flat, aimed below the ground: aimed at it, the foot hovered a few mm above
                # it (the output error balanced against the others) and the robot tipped over on
                # one line foot
                a[2] = a[5] = (self.z_ground if g is None else g.z_ground) - self.cfg.swing_depth
                outs.append(self.o_swing[k])
                des.append(Desired(a, np.zeros(6), np.zeros(6)))
        return outs, des, tuple(contact)

