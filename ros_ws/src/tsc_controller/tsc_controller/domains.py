"""The :class:`Controller` facade: domain switching and the outputs and targets of each domain
(paper §II-B, §V-A).  The domain objects live in :mod:`standing`, :mod:`jumping`, :mod:`flight` and
:mod:`landing`, their shared targets in :mod:`ground_targets`; they are imported here too.

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
  values, except that LANDING stops the pelvis yaw where it is going (``landing_yaw_stop``).
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
the standing outputs.  A LIFT_OFF seen while LANDING or STANDING (a rebound) keeps the ground outputs;
under a tracked landing plan it keeps that plan until the next touch-down's re-solve replaces it
(``rebound_keeps_landing_plan``; off: the own landing takes over).
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

from .config import ControllerConfig
from .domain_outputs import _ground_outputs
from .dynamics import Dynamics
from .flight import MOTOR_HELD_POST_T1, MOTOR_HELD_PRE_T1, Flight  # noqa: F401
from .ground_targets import GroundTargets
from .jumping import Jumping
from .landing import Landing
from .limits import TorqueLimits, speed_cap_row
from .reference import Domain, SampledReference
from .standing import Standing
from .state import StateConverter
from .tsc import TSC

#: ContactEvent.event values
LIFT_OFF, TOUCH_DOWN, BODY_CONTACT = 0, 1, 2


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
        self.limits = TorqueLimits.for_description(mjcf, cfg.motor_speed_scale, cfg.flywheel_torque)
        self.model_info = StateConverter(self.dyn)      # for state.state_from_ros(controller.model_info, js, odom)
        self.ground = GroundTargets(self.dyn, cfg, _ground_outputs(cfg.gains))
        self.standing = Standing(self.ground, cfg)
        self.jumping = Jumping(self.ground, cfg)
        self.landing = Landing(self.ground, cfg)
        self.flight = Flight(self.dyn, cfg, lambda: self.pitch)
        self.refs: dict[Domain, SampledReference] = {}
        self.landing_plan = None
        self._somersault = False
        #: why the own landing replaced the tracked landing plan in the landing under way (None: it did
        #: not): "rebound", the feet left the ground while the plan was tracked
        self.landing_fallback: str | None = None
        #: every landing the own landing did (t, reason): from a rebound's LIFT_OFF, or from the
        #: touch-down of a landing no plan was tracked in ("no landing plan")
        self.landing_fallbacks: list[tuple[float, str]] = []
        #: times of the LIFT_OFFs seen under a tracked landing plan (rebounds): with
        #: ``rebound_keeps_landing_plan`` the plan goes on until the next touch-down's re-solve arrives
        self.rebounds: list[float] = []
        self._rebound_in_air = False     # a rebound's LIFT_OFF under the kept plan, no TOUCH_DOWN yet
        self._landing_tracked = False
        self.domain = Domain.STANDING
        self.t_enter = None
        self._pending_event = None
        self.u_prev = np.zeros(self.dyn.nu)
        self._du_shares: dict = {}       # flywheel_smoothing share -> per-motor shares (_du_share)
        #: the flywheel motor's index in u (None: a robot without one)
        self._fw_motor = self.dyn.motor_names.index("flywheel") if "flywheel" in self.dyn.motor_names else None
        self.ticks = 0
        self.pitch = 0.0                 # unwrapped sagittal pelvis pitch, rad (see _update_pitch)
        self._pitch_raw = None
        self._heading = None             # the pelvis's heading and position at the jump's start (_heading_frame)
        self.fallen = False              # a BODY_CONTACT was reported: damping only, from then on
        #: the flywheel speed (rad/s) the LANDING under way may not exceed: the flight's peak, or the
        #: touch-down's if higher; "armed" until the landing's first tick reads it, None outside a LANDING
        #: (``landing_flywheel_speed_cap``)
        self.flywheel_cap = None
        #: the largest one-tick miss of the cap's prediction toward a faster wheel in the LANDING under way
        #: (rad/s; a foot rolling, a body motion the last tick's did not foresee): the cap aims that far
        #: below ``flywheel_cap``, so that a miss no larger does not carry the wheel past it
        self.flywheel_cap_guard = 0.0
        self._cap_drift = None           # the last tick's drift of the cap's prediction (_landing_flywheel_cap)
        self._flight_peak = 0.0          # the flywheel's peak |speed| over the FLIGHT under way or last
        self._w_last = None              # the last FLIGHT or LANDING tick's flywheel speed (rad/s)
        self._t_last = None              # the last tick's time: the tick period of the speed cap
        self._dt = 5e-4
        #: JUMPING references not started, (plan id, its start time, t when it was dropped): one that
        #: came after its start + max_late, or while the robot was not standing until then
        self.dropped: list[tuple[int, float, float]] = []

    # -------------------------------------------------------------- inputs
    def set_reference(self, ref: SampledReference):
        """Store a reference (the latest per domain wins).  A LANDING one after a somersault (a FLIGHT
        reference turning the pelvis by more than 90 deg) only with ``track_landing_reference``, after a
        hop only with ``track_hop_landing_reference``, and not after a rebound under the tracked plan
        (``landing_fallback``); else it is kept as ``landing_plan`` and the controller's own landing runs."""
        if ref.domain == Domain.FLIGHT and ref.has("phi_pitch") and len(ref.t):
            col = ref.names.index("phi_pitch")
            self._somersault = abs(ref.value[-1, col] - ref.value[0, col]) > math.pi / 2
        if ref.domain == Domain.LANDING and (self.landing_fallback is not None or not self._tracks_landing_plan()):
            self.landing_plan = ref
            return
        self.refs[ref.domain] = ref

    def _tracks_landing_plan(self) -> bool:
        """The landing after this flight follows the planner's landing plan (by configuration: after a
        somersault ``track_landing_reference``, after a hop ``track_hop_landing_reference``)."""
        return self.cfg.track_landing_reference if self._somersault else self.cfg.track_hop_landing_reference

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
        if domain in (Domain.FLIGHT, Domain.STANDING):
            self.landing_fallback = None
        if domain == Domain.FLIGHT:
            self.landing_plan = None
        if domain == Domain.LANDING:
            self._landing_tracked = False
            if self.domain == Domain.FLIGHT:         # a touch-down (a rebound stays in LANDING, not here)
                self.flywheel_cap = "armed"
                self.flywheel_cap_guard, self._cap_drift = 0.0, None
        else:
            self.flywheel_cap = None
        if domain == Domain.FLIGHT:
            self._flight_peak = 0.0
        self._rebound_in_air = False
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
            if ev is not None and ev[0] == TOUCH_DOWN:
                self._rebound_in_air = False
            if ev is not None and ev[0] == LIFT_OFF and self.refs.get(Domain.LANDING) is not None:
                self.rebounds.append(ev[1])
                # the plan's end does not end the landing in the air: its touch-down is re-solved
                self._rebound_in_air = self.cfg.rebound_keeps_landing_plan
                if not self.cfg.rebound_keeps_landing_plan:
                    # the feet left the ground under the tracked plan: the own landing, from now
                    self.refs.pop(Domain.LANDING, None)
                    self.landing_fallback = "rebound"
                    self.landing_fallbacks.append((ev[1], "rebound"))
                    self.ground.reanchor()
            if self.refs.get(Domain.LANDING) is not None:
                self._landing_tracked = True
            if not self._rebound_in_air and self.landing.done(t, self.refs.get(Domain.LANDING)):
                if not self._landing_tracked and self.landing_fallback is None and self._tracks_landing_plan():
                    self.landing_fallbacks.append((self.t_enter, "no landing plan"))
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
        start by minus its heading then (gravity unchanged; the base velocities are local): the jump's,
        the flight's and the landing's outputs (pitch momentum, sagittal pitch, leg and toe angles,
        pelvis axis) and the plans' x/z are in the world x-z plane, the somersault's plane only for a
        robot facing x (the planner turns the measured touch-down state the same way:
        fslip_planner.heading_frame)."""
        b = self.dyn.model.idx_qs[self.dyn.base_jid]
        x, y, z, w = q[b + 3:b + 7]
        if self._heading is None:
            psi = math.atan2(2.0 * (x * y + z * w), 1.0 - 2.0 * (y * y + z * z))
            # (heading, pivot x, y, cos and -sin of half of it and of it)
            self._heading = (psi, float(q[b]), float(q[b + 1]), math.cos(0.5 * psi), -math.sin(0.5 * psi),
                             math.cos(psi), -math.sin(psi))
            if psi != 0.0:
                self.ground.turn(psi, self._heading[1:3])
        psi, x0, y0, c, s, c2, s2 = self._heading
        if psi == 0.0:
            return q
        q = np.array(q, float)
        q[b + 3:b + 7] = (c * x - s * y, c * y + s * x, c * z + s * w, c * w - s * z)
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
    def _du_share(self):
        """Per-motor share of the torque smoothing (``flywheel_smoothing``, while this domain tracks a
        planner reference), None: all 1."""
        share = self.cfg.flywheel_smoothing.get(int(self.domain))
        if share is None or self.refs.get(self.domain) is None or self._fw_motor is None:
            return None
        out = self._du_shares.get(share)          # built once per share value, not every tick
        if out is None:
            out = self._du_shares[share] = np.ones(self.dyn.nu)
            out[self._fw_motor] = share
        return out

    def _landing_flywheel_cap(self, lb, ub, v, t):
        """The QP's row (C_x, up_x) that, in a LANDING under the tracked plan after a somersault, holds the
        flywheel at or below its flight's peak speed (``landing_flywheel_speed_cap``, limits.speed_cap_row);
        None elsewhere.

        The next tick's joint speed is predicted as w + drift + dt m.u: m = the flywheel's row of M^-1 B,
        its response to every motor torque (the wheel's own and, by reaction on the body, the legs');
        drift = the last tick's change of w less what its torques did (the body's motion, expected again)."""
        if self._t_last is not None and t > self._t_last:
            self._dt = t - self._t_last
        self._t_last = t
        if self.domain not in (Domain.FLIGHT, Domain.LANDING) or self.dyn.flywheel_v is None or self._fw_motor is None:
            self._w_last = None
            return None                                   # (a LANDING is entered from a FLIGHT only)
        i = self.dyn.flywheel_v
        w, w_last = float(v[i]), self._w_last
        self._w_last = w
        if self.domain == Domain.FLIGHT:
            self._flight_peak = max(self._flight_peak, abs(w))
        if self.flywheel_cap is None:
            return None
        m = self.dyn.Minv[i, self.dyn.motor_v]
        drift = (w - w_last) - self._dt * float(m @ self.u_prev) if w_last is not None else 0.0
        if self.flywheel_cap == "armed":                  # the landing's first tick (its drift spans the impact)
            self.flywheel_cap = max(self._flight_peak, abs(w))
            self._cap_drift = None
        else:
            if self._cap_drift is not None:               # the last prediction's miss: the drift's change
                miss = drift - self._cap_drift
                self.flywheel_cap_guard = max(self.flywheel_cap_guard, miss if w >= 0.0 else -miss)
            self._cap_drift = drift
        if not self.cfg.landing_flywheel_speed_cap or not self._somersault or self.refs.get(Domain.LANDING) is None:
            return None
        return speed_cap_row(m, w, self.flywheel_cap - self.flywheel_cap_guard, self._dt, drift, lb, ub)

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
        if self.domain in (Domain.JUMPING, Domain.FLIGHT) or (self.domain == Domain.LANDING and self._heading):
            q = self._heading_frame(q)       # the landing after a jump too: the planner plans it in that frame
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
        cap = self._landing_flywheel_cap(lb, ub, v, t)
        try:
            w_du = self.cfg.torque_smoothing.get(int(self.domain), 0.0)
            res = self.tsc.solve(outs, des, ground, lb, ub, feet, self.u_prev, w_du,
                                 self.cfg.cop_margin_domains.get(int(self.domain)), details,
                                 self.cfg.f_min_domains.get(int(self.domain)), self._du_share(), cap)
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
