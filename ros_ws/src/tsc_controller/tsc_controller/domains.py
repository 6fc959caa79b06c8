"""The :class:`Controller` facade: domain switching and the outputs and targets of each domain
(paper §II-B, §V-A).

Domains follow flip_msgs: STANDING=0, JUMPING=1, FLIGHT=2, LANDING=3 (:class:`reference.Domain`;
the references are :class:`reference.SampledReference`, the settings :class:`config.ControllerConfig`,
the quintic and leg-catch profiles in :mod:`profiles`).  Each domain is an object that owns its
outputs and builds their desired values per tick (:class:`Standing`, :class:`Jumping`,
:class:`Flight`, :class:`Landing`); the ground domains share :class:`GroundTargets` (the standing
targets, the feet's contact and swing).  The :class:`Controller` switches between them and solves the
QP of the one it is in.  Outputs per domain:

* STANDING — the jumping/landing outputs with constant desired values: H_pitch -> 0,
  L -> L_stand, (x_com, y_com) -> middle of the feet, pelvis (roll, pitch, yaw) -> (0, 0, feet heading);
  blended from the values at entry by a quintic over ``blend_time``.
* JUMPING / LANDING — Y1 = H_pitch - H_FSLIP(t); Y2 = [L, x_com, y_com, phi_pitch, phi_yaw] - desired(t)
  (eq. Y^{J/L}), plus phi_roll -> 0: the paper's sagittal outputs leave the pelvis roll of the 3D robot
  unobserved, so it is held as an extra output.  Names missing from the reference keep their standing
  values.
* FLIGHT — Y1 = H_flywheel - H_flywheel^des(t) (eq. Y^F_1);  t < T1: per-leg L and the motor joints
  except the knees held at their lift-off values q+, and the pelvis y axis held along world y (not in
  the paper: see config.DEFAULT_GAINS["axis"]);  t >= T1: per-leg L, leg angle -> -beta+, toe
  pitch -> 0, hip roll/yaw held (eq. Y^F_2), per leg since Cassie has two.

Switching: a JUMPING reference whose start time has come starts the flip (if it is not more than
``max_late`` past its start: a plan is never joined in the middle); the LIFT_OFF contact event
enters FLIGHT, TOUCH_DOWN enters LANDING; the end of the landing reference returns to STANDING.
Reference time: JUMPING from the message's start_time, FLIGHT / LANDING from the lift-off / touch-down
event (the paper plans them at those events).  Missing or late references never leave the robot
without a command: JUMPING without lift-off past its end (+ ``grace``; + up to ``push_grace`` while the
COM still rises fast) falls back to STANDING, FLIGHT
without a reference holds the lift-off posture and flywheel momentum, LANDING without a reference uses
the standing outputs.  A LIFT_OFF seen while LANDING or STANDING (a rebound) keeps the ground outputs.
The controller's own landing (after a somersault) starts with a light H_pitch weight that rises to its
standing value (``landing_H_weight``, ``landing_H_ramp``): the flywheel takes the moment of the ground
force that stops the body's forward speed, and the momentum is removed afterwards; the landing lasts
until it has been (``landing_H_done``).
A BODY_CONTACT (a fall) latches a damping-only command (``fall_damping``).

Per-foot contact (LANDING, STANDING): a foot that has come off the ground (or rocked onto toe or heel)
while its leg is unloaded loses its contact rows in the QP and gets a swing output (toe and heel back
to where it stood, flat, aimed slightly below the ground) until it is down again; with both feet off,
both keep their contact rows (a rebound).  The fallback landing lasts until its own profiles end
(leg catch and rise, momentum removal) and the momentum is out, and moves the COM target against the
centre-of-pressure offset the momentum removal needs, and with the feet where they stand now.
"""
from __future__ import annotations

import math
import time

import numpy as np
import pinocchio as pin

from . import outputs as O
from .config import ControllerConfig
from .dynamics import SIDES, Dynamics
from .limits import TorqueLimits
from .profiles import LEG_RISE_TIME, leg_catch, leg_catch_duration, quintic
from .reference import Domain, SampledReference
from .state import StateConverter
from .tsc import TSC, Desired

#: ContactEvent.event values
LIFT_OFF, TOUCH_DOWN, BODY_CONTACT = 0, 1, 2

MOTOR_HELD_PRE_T1 = tuple(f"{s}_{j}" for s in SIDES for j in ("hip_roll", "hip_yaw", "hip_pitch", "foot"))
MOTOR_HELD_POST_T1 = tuple(f"{s}_{j}" for s in SIDES for j in ("hip_roll", "hip_yaw"))

#: (ground target, index in it, reference name): the targets a JUMPING or LANDING reference sets
_REFERENCE_TARGETS = (("H_pitch", 0, "H_pitch"), ("L", 0, "L"), ("com", 0, "x_com"), ("com", 1, "y_com"),
                      ("pelvis", 0, "phi_roll"), ("pelvis", 1, "phi_pitch"), ("pelvis", 2, "phi_yaw"))


def _mk(cls, name, gains, key=None, **kw):
    w, kp, kd = gains[key or name]
    return cls(name=name, weight=w, kp=kp, kd=kd, **kw)


def _ground_outputs(gains):
    """The outputs of a ground domain (paper §V-A): H_pitch, leg length, COM x/y, pelvis roll/pitch/yaw."""
    return [_mk(O.CentroidalPitchMomentum, "H_pitch", gains), _mk(O.LegLength, "L", gains),
            _mk(O.ComPosition, "com", gains, axes=(0, 1)),
            _mk(O.PelvisOrientation, "pelvis", gains, axes=("roll", "pitch", "yaw"))]


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
            # the feet creep on the ground during a hard landing (measured: 10-20 cm over 1.5 s after a
            # backflip, until the COM was behind the heels): the COM follows where they stand now
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
        rate at once (measured after a backflip: 2.4 -> 1.3 m/s in 60 ms), and a leg still shortened
        at the profile's rate pulled the feet off the ground (F = 0 at 90 ms, a bounce)."""
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
        ramped in over ``moment_ramp``, from the measured H (value = H: no error to correct).
        A time profile (quintic from the touch-down value) was tried first: the impact took 8 of a
        backflip's 35 kg*m^2/s and the QP spent the landing's ground forces on a 100 N*m moment to
        put them back while the legs gave way; a landing that fell behind the profile got kp times its
        lag asked (180 N*m), the COM was driven off the feet and the robot fell 1.8 s after landing."""
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
        for it throw the foot about (measured: a 75 N lateral push for 0.1 s made the unloaded foot
        slide 9 cm and the robot fall)."""
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
            # could not bring it down (it rests on one end) and the robot stood on the other leg (measured
            # backflip landings: 1 fall in 6 start times with, 0 in 6 without)
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


class Standing:
    """STANDING: the ground outputs with the standing gains, held at the standing targets; the H_pitch
    weight gives way while the COM is off the feet (:meth:`H_weight`)."""
    domain = Domain.STANDING

    def __init__(self, ground: GroundTargets, cfg: ControllerConfig):
        self.ground = ground
        self.outputs = _ground_outputs({**cfg.gains, **cfg.standing_gains})
        self.H_w0 = self.outputs[0].weight       # see H_weight

    def enter(self):
        self.ground.reanchor()            # re-anchor the standing targets at the current state

    def task(self, t):
        des = self.ground.targets(t, False)
        self.H_weight()
        return self.outputs, [des[o.name] for o in self.outputs]

    def H_weight(self):
        """The STANDING H_pitch weight: its ``standing_gains`` value while the COM is over the span of
        the feet on the ground (along their heading); past its front or back, falling linearly to
        ``standing_H_edge_weight`` of it at ``standing_H_edge`` beyond and further out.

        Why: with the COM off the feet the ground cannot give the moment that brings it back, and the
        H_pitch output's momentum removal asks for the opposite moment; at full weight it costs the QP
        more than the COM error saves, so the COM stays off the feet and the flywheel takes the
        toppling moment.  Back over the feet, the removal needs no COM error and the weight is back.
        The measurements: docs/tuning.md, ``standing_H_edge``."""
        self.outputs[0].weight = self.ground.standing_H_weight(self.H_w0)


class Jumping:
    """JUMPING: the ground outputs with the jumping gains, tracking the planner's jumping reference
    (eq. Y^{J/L}) over the standing targets STANDING began (names the reference lacks keep them)."""
    domain = Domain.JUMPING

    def __init__(self, ground: GroundTargets, cfg: ControllerConfig):
        self.ground, self.cfg = ground, cfg
        self.outputs = _ground_outputs({**cfg.gains, **cfg.jumping_gains})

    def enter(self):
        pass                              # the standing targets go on (turned into the heading frame)

    def task(self, t, ref):
        des = self.ground.targets(t, False)
        self.ground.follow(des, ref.sample(t - ref.start_time))
        return self.outputs, [des[o.name] for o in self.outputs]

    def push_over(self, t, t_end):
        """JUMPING has run past its reference without a lift-off: over after ``grace``, or after
        ``push_grace`` while the COM still rises faster than ``push_rising`` (see the config)."""
        late = t - t_end
        if late <= self.cfg.grace:
            return False
        dyn = self.ground.dyn
        rising = float(dyn.hg_lin[2]) / dyn.mass > self.cfg.push_rising
        return not rising or late > self.cfg.push_grace


class Landing:
    """LANDING: with a landing reference (after a hop; after a somersault only with
    ``track_landing_reference``) the ground outputs with the default gains track it over the standing
    targets; without one, the controller's own landing: the standing targets (leg catch, momentum
    removal, COM against the removal's CoP offset) with an H_pitch weight rising from
    ``landing_H_weight`` over ``landing_H_ramp``."""
    domain = Domain.LANDING

    def __init__(self, ground: GroundTargets, cfg: ControllerConfig):
        self.ground, self.cfg = ground, cfg
        self.o_H = _mk(O.CentroidalPitchMomentum, "H_pitch", cfg.gains)      # the own landing's; weight set per tick
        self.own_outputs = [self.o_H, ground.o_L, ground.o_com, ground.o_pel]

    def enter(self):
        self.ground.reanchor()            # re-anchor the standing targets at the current state

    def task(self, t, ref, t_enter):
        tau = 0.0 if ref is None else max(0.0, t - max(t_enter, ref.start_time))
        g = self.ground
        des = g.targets(t, True)
        if ref is not None:
            g.follow(des, ref.sample(tau))
            outs = g.outputs
        else:
            cfg = self.cfg
            self.o_H.weight = float(quintic(cfg.landing_H_weight, g.o_H.weight, cfg.landing_H_ramp,
                                            t - g.stand["t0"])[0])
            outs = self.own_outputs
        return outs, [des[o.name] for o in outs]

    def done(self, t, ref):
        """The landing is over: its reference has ended or, without one, the own landing
        (:meth:`GroundTargets.landing_done`), not after blend_time: re-anchoring the standing targets
        mid-catch throws the robot."""
        return ref.start_time + ref.duration < t if ref is not None else self.ground.landing_done(t)


class Flight:
    """FLIGHT: the flywheel's momentum (eq. Y^F_1) or, with a planned pelvis pitch, that pitch; per-leg
    length; before T1 the motor joints but the knees held at their lift-off values (and, in a
    somersault, the pelvis axis along world y), after T1 the feet placed for the touch-down (leg
    angle, toe pitch) and the hips' roll and yaw held (eq. Y^F_2)."""
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
                q_pre=q_pre, q_post=self.o_j_post.evaluate(dyn)[0],
                beta=[o.evaluate(dyn)[0] for o in self.o_beta])
        f = self.state
        smp = ref.sample(tau) if ref is not None else {}
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
            outs, des = [self.o_Hfw], [Desired(np.array([self._momentum_transmission(smp, pitch)]), z, z)]
        outs = outs + self.o_Lleg
        des = des + [d("L", f["L"][k]) for k in range(2)]
        if tau < T1:
            if somersault and self.o_axis.weight > 0.0:          # see config.DEFAULT_GAINS["axis"]
                outs.append(self.o_axis)
                des.append(Desired(self._z2, self._z2, self._z2))
            outs.append(self.o_j_pre)
            des.append(Desired(f["q_pre"], np.zeros(len(f["q_pre"])), np.zeros(len(f["q_pre"]))))
        else:
            bplus = ref.parameters.get("beta_liftoff") if ref is not None else None
            # the foot placement is a world leg angle for the pelvis at its final pitch theta_T; with
            # ``flight_legs_on_pelvis`` it is offset by (theta - theta_T) and its rates (see the config)
            off = np.zeros(3)
            if "phi_pitch" in smp and self.cfg.flight_legs_on_pelvis:
                if f.get("ref") is not ref:                  # final pitch of this flight reference
                    f["ref"], f["th_T"] = ref, ref.sample(ref.duration)["phi_pitch"][0]
                th_T = f["th_T"]
                R = dyn.data.oMi[dyn.base_jid].rotation
                w_p = float(R[1] @ dyn.v[self.o_Hfw._base_v + 3:self.o_Hfw._base_v + 6])
                # pelvis (with legs) pitch acceleration from the last flywheel torque (its reaction):
                # without it the legs lag the pelvis's deceleration by ~0.45 rad (kp 100, kd 20
                # against ~80 rad/s^2) and land with the feet far ahead
                a_p = -float(u_prev[-1]) * float(R[1] @ self.o_Hfw._a) / max(self._rest_inertia(), 1e-3)
                off = np.array([pitch - th_T, w_p, a_p])
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

    def _rest_inertia(self):
        """Centroidal pitch inertia of the robot without the flywheel's spin inertia (sum_i I_i)."""
        dyn = self.dyn
        pin.ccrba(dyn.model, dyn.data, dyn.q, dyn.v)            # data.Ig: centroidal composite inertia
        return float(dyn.data.Ig.inertia[1, 1]) - self.o_Hfw._I

    def _momentum_transmission(self, smp, pitch):
        """Eq. (momentumTrans): H_fw^des = H_pitch - (omega_des - k (theta_pelvis - theta_des)) * sum_i I_i,
        with theta_des, omega_des from the reference's ``phi_pitch`` (value, d_value) or 0 (level pelvis)."""
        H_pitch = float(self.dyn.Ag[4] @ self.dyn.v)
        th_des, om_des = (smp["phi_pitch"][0], smp["phi_pitch"][1]) if "phi_pitch" in smp else (0.0, 0.0)
        om_cl = om_des - self.cfg.k_theta * (pitch - th_des)
        return H_pitch - om_cl * self._rest_inertia()


class Controller:
    """TSC facade: ``Controller(mjcf_str).compute(q, v, t) -> (u[11], info)``.  Switches the domain on
    references and contact events and asks the domain's object (``standing``, ``jumping``, ``flight``,
    ``landing``) for its outputs and desired values; the ground domains share ``ground``."""

    def __init__(self, mjcf: str, config: ControllerConfig | None = None, **overrides):
        cfg = config or ControllerConfig()
        for k, val in overrides.items():
            setattr(cfg, k, val)
        self.cfg = cfg
        self.dyn = Dynamics(mjcf, rigid_springs=cfg.rigid_springs, backend=cfg.backend)
        self.tsc = TSC(self.dyn, solver=cfg.solver, reg=cfg.reg, mu=cfg.mu, f_min=cfg.f_min, cop_margin=cfg.cop_margin)
        self.limits = TorqueLimits(speed_scale=cfg.motor_speed_scale, flywheel_torque=cfg.flywheel_torque)
        self.model_info = StateConverter(self.dyn)      # for state.state_from_ros(controller.model_info, js, odom)
        self.ground = GroundTargets(self.dyn, cfg, _ground_outputs(cfg.gains))
        self.standing = Standing(self.ground, cfg)
        self.jumping = Jumping(self.ground, cfg)
        self.landing = Landing(self.ground, cfg)
        self.flight = Flight(self.dyn, cfg, lambda: self.pitch)
        self.refs: dict[Domain, SampledReference] = {}
        self.landing_plan = None
        self._somersault = False
        self.domain = Domain.STANDING
        self.t_enter = None
        self._pending_event = None
        self.u_prev = np.zeros(self.dyn.nu)
        self.ticks = 0
        self.pitch = 0.0                 # unwrapped sagittal pelvis pitch, rad (see _update_pitch)
        self._pitch_raw = None
        self._heading = None             # (heading, x, y) of the pelvis at the jump's start (_heading_frame)
        self.fallen = False              # a BODY_CONTACT was reported: damping only, from then on
        #: JUMPING references not started, (plan id, its start time, t when it was dropped): one that
        #: came after its start + max_late, or while the robot was not standing until then
        self.dropped: list[tuple[int, float, float]] = []

    # -------------------------------------------------------------- inputs
    def set_reference(self, ref: SampledReference):
        """Store a reference (the latest per domain wins).  A LANDING one after a somersault (a FLIGHT
        reference turning the pelvis by more than 90 deg) only with ``track_landing_reference``; else it
        is kept as ``landing_plan`` and the controller's own landing runs."""
        if ref.domain == Domain.FLIGHT and ref.has("phi_pitch") and len(ref.t):
            col = ref.names.index("phi_pitch")
            self._somersault = abs(ref.value[-1, col] - ref.value[0, col]) > math.pi / 2
        if ref.domain == Domain.LANDING and self._somersault and not self.cfg.track_landing_reference:
            self.landing_plan = ref
            return
        self.refs[ref.domain] = ref

    def on_contact_event(self, kind: int, *args):
        """LIFT_OFF (0) or TOUCH_DOWN (1): ``on_contact_event(kind, t)`` or
        ``on_contact_event(kind, domain_entered, t)`` (flip_msgs/ContactEvent fields)."""
        t = args[-1]
        if int(kind) == BODY_CONTACT:
            self.fallen = True
            return
        self._pending_event = (int(kind), float(t))

    # -------------------------------------------------------------- domain logic
    def _enter(self, domain, t):
        self.domain = Domain(domain)
        self.t_enter = t
        self._domain_object(domain).enter()

    def _domain_object(self, domain):
        return (self.standing, self.jumping, self.flight, self.landing)[int(domain)]

    def _switch(self, t):
        ev, self._pending_event = self._pending_event, None
        d = self.domain
        # A LIFT_OFF while landing or standing is a rebound of a few ms, not a flight: the ground
        # outputs stay (switching to the flight posture hold there makes the landing chatter).
        if d == Domain.STANDING:
            r = self.refs.get(Domain.JUMPING)
            if r is not None and r.start_time <= t:
                if t - r.start_time <= self.cfg.max_late:
                    self._heading = None
                    self._enter(Domain.JUMPING, t)
                else:                              # arrived (or was processed) too late: never start mid-plan
                    self.refs.pop(Domain.JUMPING, None)
                    self.dropped.append((r.plan_id, r.start_time, t))
        elif d == Domain.JUMPING:
            r = self.refs.get(Domain.JUMPING)
            if ev is not None and ev[0] == LIFT_OFF:
                self._enter(Domain.FLIGHT, ev[1])
            elif r is None or self.jumping.push_over(t, r.start_time + r.duration):
                self.refs.pop(Domain.JUMPING, None)
                self._enter(Domain.STANDING, t)
        elif d == Domain.FLIGHT:
            if ev is not None and ev[0] == TOUCH_DOWN:
                self.refs.pop(Domain.JUMPING, None)
                self.refs.pop(Domain.FLIGHT, None)
                self._enter(Domain.LANDING, ev[1])
        elif d == Domain.LANDING:
            if self.landing.done(t, self.refs.get(Domain.LANDING)):
                self.refs.pop(Domain.LANDING, None)
                self.refs.pop(Domain.FLIGHT, None)
                self._enter(Domain.STANDING, t)

    def _task(self, t):
        """(on the ground, outputs, desired values) of the domain at t."""
        dom = self.domain
        if dom == Domain.STANDING:
            return True, *self.standing.task(t)
        if dom == Domain.JUMPING:
            return True, *self.jumping.task(t, self.refs[Domain.JUMPING])
        if dom == Domain.LANDING:
            return True, *self.landing.task(t, self.refs.get(Domain.LANDING), self.t_enter)
        return False, *self.flight.task(t, self.refs.get(Domain.FLIGHT), self.t_enter, self.pitch,
                                        self._somersault, self.u_prev)

    def _heading_frame(self, q):
        """``q`` with the floating base turned about the vertical through its position at the jump's
        start by minus its heading then (gravity unchanged; the base velocities are local): the jump's
        and the flight's outputs (pitch momentum, sagittal pitch, leg and toe angles, pelvis axis) and
        the plan's x/z are in the world x-z plane, the somersault's plane only for a robot facing x."""
        b = self.dyn.model.idx_qs[self.dyn.base_jid]
        x, y, z, w = q[b + 3:b + 7]
        if self._heading is None:
            self._heading = (math.atan2(2.0 * (x * y + z * w), 1.0 - 2.0 * (y * y + z * z)),
                             float(q[b]), float(q[b + 1]))
            if self._heading[0] != 0.0:
                self.ground.turn(*self._heading[:1], self._heading[1:])
        psi, x0, y0 = self._heading
        if psi == 0.0:
            return q
        c, s = math.cos(0.5 * psi), -math.sin(0.5 * psi)
        q = np.array(q, float)
        q[b + 3:b + 7] = (c * x - s * y, c * y + s * x, c * z + s * w, c * w - s * z)
        c2, s2 = math.cos(psi), -math.sin(psi)
        dx, dy = q[b] - x0, q[b + 1] - y0
        q[b:b + 2] = (x0 + c2 * dx - s2 * dy, y0 + s2 * dx + c2 * dy)
        return q

    def _update_pitch(self):
        """Unwrapped sagittal pitch of the pelvis: the angle of its x axis in the world x-z plane,
        atan2(-R_20, R_00), continued across ±pi from tick to tick (a somersault turns it by ±2pi;
        the ZYX Euler pitch is singular at ±pi/2)."""
        R = self.dyn.R_base
        raw = math.atan2(-float(R[2, 0]), float(R[0, 0]))
        if self._pitch_raw is None:
            self.pitch = raw
        else:
            self.pitch += (raw - self._pitch_raw + math.pi) % (2 * math.pi) - math.pi
        self._pitch_raw = raw

    def _fallen_command(self, v, t0):
        """Damping only, after a fall (see ``ControllerConfig.fall_damping``)."""
        w = np.asarray(v, float)[self.dyn.motor_v]
        lb, ub = self.limits.bounds(w)
        u = np.clip(-self.cfg.fall_damping * w, lb, ub)
        self.u_prev = u
        self.ticks += 1
        return u, dict(tick_time=time.perf_counter() - t0, qp_status="fallen", domain=int(self.domain),
                       qp_time=0.0, qp_iter=0, timing={}, grf=(0.0, 0.0))

    # -------------------------------------------------------------- the tick
    def compute(self, q, v, t, details: bool = True):
        """One TSC tick: returns (u (11,), info dict).  ``details=False`` leaves the predicted forces,
        ground reaction and output errors out of ``info`` (the same u)."""
        t0 = time.perf_counter()
        self._switch(t)                            # events and references only, no state needed
        if (self.cfg.rigid_springs and self.domain != Domain.FLIGHT
                and int(self.domain) in self.cfg.spring_rate_zero_domains):
            # see ControllerConfig.spring_rate_zero_domains
            v = np.array(v, float)
            v[self.dyn.spring_v] = 0.0
        if self.fallen:
            return self._fallen_command(v, t0)
        if self.domain in (Domain.JUMPING, Domain.FLIGHT):
            q = self._heading_frame(q)
        self.dyn.update(q, v)
        t_dyn = time.perf_counter() - t0
        self._update_pitch()
        if self.t_enter is None:
            self.t_enter = t
        if self.domain in (Domain.LANDING, Domain.STANDING):
            self.ground.update_feet()
        else:                  # FLIGHT; JUMPING: the feet leave the ground on purpose at the end of the push-off
            self.ground.reset_feet()
        ground, outs, des = self._task(t)
        feet = (True, True)
        if ground:
            outs, des, feet = self.ground.swing(outs, des)
        lb, ub = self.limits.bounds(v[self.dyn.motor_v])
        try:
            w_du = self.cfg.torque_smoothing.get(int(self.domain), 0.0)
            res = self.tsc.solve(outs, des, ground, lb, ub, feet, self.u_prev, w_du,
                                 self.cfg.cop_margin_domains.get(int(self.domain)), details,
                                 self.cfg.f_min_domains.get(int(self.domain)))
            u, status = res.u, res.status
        except np.linalg.LinAlgError as e:     # singular M or J M^-1 J^T: hold the previous command
            res, u, status = None, np.clip(self.u_prev, lb, ub), f"linalg_error: {e}"
        self.u_prev = u
        self.ticks += 1
        info = dict(tick_time=time.perf_counter() - t0, qp_status=status, domain=int(self.domain),
                    qp_time=res.solve_time if res else 0.0, qp_iter=res.iterations if res else 0,
                    timing=dict(dynamics=t_dyn, **(res.timing if res else {})))
        if not details:
            return u, info
        if res is not None:
            F = res.forces
            info["forces"] = F
            if not ground:
                info["grf"] = (0.0, 0.0)
            elif all(feet):
                info["grf"] = (float(F[2] + F[4]), float(F[7] + F[9]))
            else:
                fn = float(F[2] + F[4])
                info["grf"] = (fn, 0.0) if feet[0] else (0.0, fn)
            info["feet_contact"] = feet
            info["errors"] = res.y
        else:
            info["grf"] = (0.0, 0.0)
        return u, info
