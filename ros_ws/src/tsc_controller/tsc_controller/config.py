"""The controller's settings: :class:`ControllerConfig`, its default output gains, and
:func:`config_overrides` (tsc_node's ``controller`` parameter, ``flip run|stand --controller``).

Each field's comment says what it is and why it has its value; how each value was found (the
measurements, tallies and settings tried) is in docs/tuning.md, one section per field.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .dynamics import BACKENDS
from .reference import Domain
from .tsc import SOLVERS

#: name: (weight, kp, kd) of each output (paper §V-A; Ydot1_des = -kp Y1, Ydd2_des = -kp Y2 - kd Ydot2,
#: eq. (Ydes); weight: its row's weight in the QP, eq. (QP))
DEFAULT_GAINS = {
    # name: (weight, kp, kd)
    "H_pitch": (1.0, 10.0, 0.0),
    "L": (10.0, 100.0, 20.0),
    # COM x, y on the ground.  Weight 100: a lower one lets the QP take the landing's momentum removal
    # from horizontal ground forces and run the COM off the feet (docs/tuning.md, gains.com)
    "com": (100.0, 100.0, 20.0),
    "pelvis": (1.0, 100.0, 20.0),
    "H_flywheel": (1.0, 20.0, 0.0),
    # leg length per leg in FLIGHT (the tuck).  Weight 100: with less the QP gives up the tuck and folds
    # the legs to help a saturated flywheel turn the body, landing on short legs (docs/tuning.md)
    "L_leg": (100.0, 100.0, 20.0),
    "joints": (1.0, 100.0, 20.0),
    "beta_leg": (10.0, 100.0, 20.0),
    # FLIGHT after T1: the feet flat for the touch-down (eq. Y^F_2's toe pitch).  Stiff, because a
    # frontflip's feet are near vertical at T1 and otherwise touch down heel first; it trades against
    # flip C (docs/tuning.md, gains.toe_pitch)
    "toe_pitch": (10.0, 900.0, 60.0),
    "swing": (10.0, 400.0, 40.0),
    "pitch": (10.0, 100.0, 20.0),
    # FLIGHT of a somersault before T1: the pelvis y axis (the flywheel's) held along world y
    # (PelvisAxisTilt, not in the paper).  Pitch is the tucked robot's intermediate principal axis, so
    # the turn about it with the flywheel spinning against the body is unstable (a gyrostat): roll/yaw
    # grow by touch-down unless held.  Not in a hop (docs/tuning.md, gains.axis)
    "axis": (10.0, 100.0, 20.0),
    # FLIGHT of a somersault: the legs' hip pitch and knee held equal (LegAsymmetry at 0; not in the
    # paper).  Left to the per-leg outputs, one leg swings ahead of the other, the pelvis yaws, and after
    # T1 the flywheel's momentum growing along the yawed pelvis axis turns into a yaw rate that rolls the
    # robot over in the landing: backflips from a stance with one foot 4 mm ahead, and second backflips,
    # fell.  It costs the axis hold part of its reach (docs/tuning.md, gains.leg_symmetry).  Not in a hop
    "leg_symmetry": (10.0, 100.0, 20.0),
}

# JUMPING overrides (name: (weight, kp, kd)).  COM weight 100 as on the ground, so the push leaves with
# the planned forward speed; H_pitch keeps its ground weight 1, since a higher one makes the QP unload
# the feet to shape the momentum (docs/tuning.md, jumping_gains)
JUMPING_GAINS = {"com": (100.0, 100.0, 20.0)}

# LANDING overrides under a tracked landing plan: H_pitch weight 0.3.  Late in the landing, with the
# centre of pressure at the heels, only a ground force whose moment changes H brings a COM that lags its
# plan back over the feet; at weight 1 the QP keeps H on the plan and lets the COM run off the heels
# (docs/tuning.md, landing_gains)
LANDING_GAINS = {"H_pitch": (0.3, 10.0, 0.0)}

# STANDING overrides: COM kd 40, which damps the foot-to-foot rocking a push starts (with 20 it went on
# until the robot fell; docs/tuning.md, standing_gains)
STANDING_GAINS = {"com": (100.0, 100.0, 40.0)}


@dataclass
class ControllerConfig:
    """Settings of :class:`tsc_controller.domains.Controller` (robot parameters aside: ROBOT_FIELDS).
    Domain-keyed dicts map a :class:`Domain` number to the value there."""
    # QP solver (tsc.SOLVERS); daqp is the fastest on this QP, "proxqp" also works
    solver: str = "daqp"
    # the tick's dynamics, constraint elimination and task rows: "native" compiled (tsc_controller._native),
    # "python" the numpy reference it is tested against (tests/unit/test_tsc_native.py)
    backend: str = "native"
    # native backend: the ground domains' per-tick targets (feet contact and anchors, momentum removal,
    # leg catch, COM and pelvis blends) in C++ (_native.GroundTargets) rather than their Python
    # reference: the same torques to the bit (tests/unit/test_tsc_native.py), a faster tick
    compiled_targets: bool = True
    reg: float = 1e-4                 # weight of reg ||u||^2 in the QP (tsc module doc): keeps it strictly convex
    mu: float = 0.6                   # friction coefficient of the QP's friction pyramid at toe and heel
    f_min: float = 1.0                # N, least normal force at toe and heel on the ground (unilateral)
    # domain -> f_min there (overrides).  JUMPING and LANDING 25 N: near 0 the QP plans all but unloaded
    # feet whenever its tasks ask the body to decelerate, and the compliant legs then leave the ground
    # (a rebound, an aborted crouch).  STANDING keeps f_min (docs/tuning.md)
    f_min_domains: dict = field(default_factory=lambda: {1: 25.0, 3: 25.0})
    cop_margin: float = 0.0           # centre of pressure kept this fraction of the foot length from its ends
    # domain -> cop_margin there (overrides).  JUMPING 0.2: the flat-foot QP otherwise loads the heels
    # only to f_min and the real feet roll onto the toes in the push-off, which then falls short
    # (docs/tuning.md)
    cop_margin_domains: dict = field(default_factory=lambda: {1: 0.2})
    # leaf springs held rigid in the QP's model (qddot_spring = 0 rows, dynamics module doc): with them
    # free the ground forces do not depend on u at an instant and the torque-only QP cannot shape them
    rigid_springs: bool = True
    motor_speed_scale: float = 1.0    # leg motors' no-load speeds x this, as in the simulator
    flywheel_torque: float | None = None   # flywheel motor's limit, N·m (None or 0: 195), as in the simulator
    # domains in which the controller is fed zero leaf-spring rates (the rigid-spring model's).  JUMPING:
    # the measured rates make the torques chatter at the spring frequency and the feet unload early in
    # the push.  Not STANDING / LANDING (the spring modes would go undamped), never FLIGHT (the momenta
    # need every rate).  docs/tuning.md
    spring_rate_zero_domains: tuple = (1,)
    L_stand: float | None = None      # m, standing leg length (default: leg length of the first state seen)
    blend_time: float = 0.8           # s, quintic from the state at entry to the standing targets
    grace: float = 0.1                # s a JUMPING reference may run over its end before STANDING takes over
    # ... unless the push is still under way: with the COM rising faster than ``push_rising`` the
    # JUMPING outputs (held at the plan's end) stay up to ``push_grace`` past the end, so that a push
    # lagging its plan at the knees' torque limit still gets its flight (docs/tuning.md)
    push_grace: float = 0.3           # s
    push_rising: float = 1.0          # m/s
    # JUMPING after the plan's deepest crouch: the reference sampled where its leg length is the
    # measured one (its velocity, momentum and COM as functions of the leg's extension), not at the
    # clock's time.  Off: the plans' flights need the push's overshoot (docs/tuning.md)
    push_phase_from_leg: bool = False
    max_late: float = 0.01            # s after its start_time a JUMPING reference may still start
    # T1 (paper, eq. Y^F_2) as a fraction of the flight time, where the reference gives none: before T1
    # the flight holds the lift-off posture, after it the legs are placed for the touch-down
    t1_fraction: float = 0.75
    # s: the FLIGHT reference is sampled this far ahead of the time since the LIFT_OFF event, so the
    # turn ends that much before the planned touch-down: the event comes 10 ms after the lift-off's
    # onset, and an early touch-down (flip D) otherwise meets a body still turning (docs/tuning.md)
    flight_lead: float = 0.01
    # m/s^2, the leg's constant deceleration after a touch-down in the controller's own landing
    # (profiles.leg_catch): hard enough to stop the sink within the stroke, gentle enough not to
    # rebound (docs/tuning.md, catch_decel and landing_moment)
    catch_decel: float = 25.0
    # N*m, the pitch moment the own landing uses to remove H_pitch, dH/dt = -clip(kp H, +-M) (see
    # GroundTargets._momentum_removal): what the feet can give in the landing's first seconds
    landing_moment: float = 8.0
    # N*m: the removal moment from landing_late_after (s) into the landing or standing on, ramped in over
    # moment_ramp (0: landing_moment throughout): by then the robot stands still on both feet and takes
    # more, and the flywheel's momentum after flip A is out in ~8 s instead of ~13.5 (docs/tuning.md)
    landing_moment_late: float = 16.0
    landing_late_after: float = 2.0
    # The own LANDING's H_pitch weight starts at landing_H_weight and rises to its ``gains`` value over
    # landing_H_ramp (s, quintic), so that the flywheel takes the moment of the backward ground force
    # that stops a forward touch-down, and the COM stops over the feet (docs/tuning.md)
    landing_H_weight: float = 0.1
    landing_H_ramp: float = 1.0
    # kg*m^2/s: the own landing lasts until |H_pitch| is below this (and its profiles have ended):
    # handed to STANDING with momentum left, the robot falls (docs/tuning.md)
    landing_H_done: float = 2.0
    # s: LANDING brings the pelvis yaw to rest at psi0 + psi_dot0 * landing_yaw_stop / 2 (where a constant
    # deceleration from its touch-down rate over this time stops it), not back to the feet's heading;
    # STANDING does that.  With the flywheel's momentum h along the pelvis y axis, a pelvis yaw rate is a
    # roll moment h * psi_dot on the feet: stopping a touch-down's yaw rate asks it while the impact loads
    # both feet, turning the pelvis back asks it again when they carry only the robot's weight, and it
    # tips over sideways (docs/tuning.md).  None: to the feet's heading
    landing_yaw_stop: float | None = 0.32
    L_min: float = 0.50               # m, shortest leg the fallback landing may use
    # STANDING: once the COM is past the front or back of the feet on the ground (along their heading)
    # the H_pitch weight falls linearly, to standing_H_edge_weight of its value standing_H_edge (m)
    # beyond (0: off; Standing.H_weight): the QP then brings the COM back over the feet
    # instead of holding the momentum removal (docs/tuning.md)
    standing_H_edge: float = 0.03
    standing_H_edge_weight: float = 0.3
    com_shift: float = 0.5            # fraction of the momentum-removal CoP offset taken by moving the COM
    k_theta: float = 10.0             # 1/s, pitch feedback of the momentum transmission (eq. momentumTrans)
    # FLIGHT with a planned pelvis pitch (``phi_pitch``): track it as an output of its own (value, rate
    # and acceleration; the QP's full dynamics find the flywheel torque) instead of eq. (momentumTrans)'s
    # flywheel momentum (the paper's Y^F_1): that one lands B, F, A, D as well but fails flip C, whose
    # feet then come down 0.25 m ahead of the COM.  Needs the FLIGHT torque smoothing (docs/tuning.md)
    flight_pitch_output: bool = True
    # FLIGHT after T1: the foot placement (a world leg angle for the pelvis at its final pitch) is aimed
    # through the measured pelvis pitch, i.e. the legs ride with the pelvis until it gets there; aimed
    # at the world angle at once they throw the pelvis round (docs/tuning.md)
    flight_legs_on_pelvis: bool = True
    # FLIGHT of a somersault: the hips turn the legs to their touch-down angle on the pelvis during the
    # tuck's extension (T1/2 .. T1) instead of after T1.  On, the backflip lands with the feet where the
    # plan puts them and no momentum growth in the landing; off by default, since A, C and D then land
    # less often (docs/tuning.md, flight_legs_preplaced)
    flight_legs_preplaced: bool = False
    # FLIGHT of a somersault after T1: the leg angles' weight (gains' beta_leg weight otherwise).  The foot
    # placement outranks the pelvis pitch (weight 10), so the QP does not swing the legs to help a
    # saturated flywheel turn the body.  Not in a hop (docs/tuning.md)
    somersault_beta_weight: float = 100.0
    # LANDING after a somersault: track the planner's landing re-solve (paper §III-C), or (False) land
    # with the controller's own profiles (leg catch, bounded momentum removal), which are also what runs
    # when no landing reference arrives (and after a rebound, with rebound_keeps_landing_plan off)
    track_landing_reference: bool = True
    # LANDING under the tracked plan: a rebound (a LIFT_OFF) keeps that plan until the re-solve of the
    # next touch-down replaces it (paper §III-C: each touch-down is re-solved from its measured state),
    # or (False) hands the rest of the landing to the own landing (docs/tuning.md)
    rebound_keeps_landing_plan: bool = True
    # s after a touch-down under the tracked plan (the impact's span): the plan's momentum profile is then
    # scaled to the momentum measured, by at most 1 (Landing.scale_to_impact).  The plan is solved from the
    # pre-impact state; tracked as solved it put back what the impact took out (a backflip: -35.4 ->
    # -37.5 kg m^2/s within 40 ms, into the flywheel).  0: off (docs/tuning.md)
    landing_impact_time: float = 0.01
    # LANDING under the tracked plan after a somersault: the flywheel no faster than its flight's peak
    # w_max.  One QP row (limits.speed_cap_row) keeps the next tick's speed, predicted from this tick's
    # torques and the last tick's drift, within w_max less the largest miss of that prediction in the
    # landing so far (Controller.flywheel_cap_guard); above it a brake.  The flight is what sizes the
    # flywheel's speed (paper Table I, w_max); the landing takes the momentum out through the feet, and what
    # the flywheel may not take goes into the body's pitch.  Without it a backflip touching down with its
    # COM behind the feet followed its plan's growing momentum into the flywheel, up to 3 % past the
    # flight's peak; capped at the touch-down's speed instead, the perturbed landings of `flip sweep` lost
    # 41 of 225 (docs/tuning.md)
    landing_flywheel_speed_cap: bool = True
    # LANDING after a hop (no turn, nothing to stop): the same choice.  Off: the hop's re-solve, planned
    # from the pre-impact sink rate, unloads the feet ~80 ms after the touch-down; with Cassie's
    # published motor curve the paper's robot then fell in 1 of 3 graph runs (own landing: no rebound,
    # docs/measurements.md)
    track_hop_landing_reference: bool = False
    # m/s: the landing's leg catch re-anchors on the body's sink rate (GroundTargets._leg_catch) when the
    # profile shortens the leg faster than the body sinks by more than this
    catch_slack: float = 0.1
    moment_ramp: float = 0.3          # s over which the landing's momentum-removal moment ramps in
    per_foot_contact: bool = True     # on the ground, a foot that has come off it loses its contact rows
    foot_lift: float = 0.008          # m above the ground at which a foot counts as off it
    foot_land: float = 0.004          # m above the ground at which it counts as back on it
    foot_loaded_spring: float = 8.0   # N*m shin-spring torque above which a leg counts as loaded (on the ground)
    swing_depth: float = 0.02         # m below the ground the swing foot is aimed at
    gains: dict = field(default_factory=lambda: dict(DEFAULT_GAINS))
    jumping_gains: dict = field(default_factory=lambda: dict(JUMPING_GAINS))   # overrides in JUMPING
    standing_gains: dict = field(default_factory=lambda: dict(STANDING_GAINS))  # overrides in STANDING
    landing_gains: dict = field(default_factory=lambda: dict(LANDING_GAINS))    # in LANDING with a plan
    # domain -> w of w ||u - u_prev||^2 in the QP (torque smoothing).  Without it the torques chatter
    # against the leaf springs: the feet unload early in the push (JUMPING), the springs ring and the
    # legs stretch (FLIGHT with the pitch output), landings fail (LANDING).  docs/tuning.md
    torque_smoothing: dict = field(default_factory=lambda: {0: 10.0, 1: 10.0, 2: 10.0, 3: 10.0})
    # domain -> the flywheel motor's share of that smoothing while the domain tracks a planner reference
    # (absent: 1).  LANDING 0.1: the flywheel drives no spring, and fully smoothed it kept the flight's
    # braking torque (~-170 N*m after a backflip) on for ~25 ms after the touch-down, past the plan's, and
    # spun the flywheel past its flight speed; at 0 its torque chattered through one flip A's rebounds; in
    # the own landing (no plan) 0.1 collapsed the paper robot's 0.1 m drop (docs/tuning.md)
    flywheel_smoothing: dict = field(default_factory=lambda: {3: 0.1})
    # after a BODY_CONTACT (a fall) the motors only damp: u = -fall_damping * (motor velocity), within
    # the limits; the flywheel is braked the same way, rather than balancing a fallen robot on it
    fall_damping: float = 5.0         # N*m*s/rad


#: ControllerConfig fields that describe the robot, not the controller: they come from the robot's
#: own parameters (motor_speed_scale, flywheel_torque), the same in simulator, planner and controller
ROBOT_FIELDS = ("motor_speed_scale", "flywheel_torque")
_DOMAIN_KEYED = ("cop_margin_domains", "f_min_domains", "torque_smoothing", "flywheel_smoothing")


def config_overrides(text: str) -> dict:
    """ControllerConfig overrides from a JSON object (the ``controller`` parameter of ``tsc_node``,
    ``flip run --controller``): field -> value; ``gains`` / ``jumping_gains`` / ``standing_gains`` /
    ``landing_gains`` entries (name ->
    [weight, kp, kd]) are merged into the defaults; domain-keyed dicts take domain numbers or names
    ({"JUMPING": 0.2} or {"1": 0.2}).  Raises ValueError with the reason for anything else."""
    import json
    try:
        raw = json.loads(text) if text and text.strip() else {}
    except json.JSONDecodeError as e:
        raise ValueError(f"controller overrides are not JSON: {e}") from None
    if not isinstance(raw, dict):
        raise ValueError("controller overrides must be a JSON object {field: value}")
    base = ControllerConfig()
    fields = set(ControllerConfig.__dataclass_fields__)
    out = {}
    for key, val in raw.items():
        if key in ROBOT_FIELDS:
            raise ValueError(f"{key!r} is a robot parameter: set it for the whole robot "
                             f"(--{key.replace('_', '-')}), not for the controller alone")
        if key not in fields:
            raise ValueError(f"unknown controller setting {key!r}; known: {', '.join(sorted(fields - set(ROBOT_FIELDS)))}")
        cur = getattr(base, key)
        if key in ("gains", "jumping_gains", "standing_gains", "landing_gains"):
            if not isinstance(val, dict):
                raise ValueError(f"{key} must be an object name -> [weight, kp, kd]")
            merged = dict(cur)
            for name, g in val.items():
                if name not in DEFAULT_GAINS:
                    raise ValueError(f"{key}: unknown output {name!r}; known: {', '.join(DEFAULT_GAINS)}")
                if not (isinstance(g, (list, tuple)) and len(g) == 3
                        and all(isinstance(x, (int, float)) and math.isfinite(x) and x >= 0 for x in g)):
                    raise ValueError(f"{key}.{name} must be [weight, kp, kd], three numbers >= 0")
                merged[name] = tuple(float(x) for x in g)
            out[key] = merged
        elif key in _DOMAIN_KEYED:
            if not isinstance(val, dict):
                raise ValueError(f"{key} must be an object domain -> number")
            d = {}
            for dk, dv in val.items():
                try:
                    dom = Domain[dk] if dk in Domain.__members__ else Domain(int(dk))
                except (ValueError, KeyError):
                    raise ValueError(f"{key}: {dk!r} is not a domain ({', '.join(Domain.__members__)} or 0-3)") from None
                if not (isinstance(dv, (int, float)) and math.isfinite(dv) and dv >= 0):
                    raise ValueError(f"{key}.{dk} must be a number >= 0")
                d[int(dom)] = float(dv)
            if key == "cop_margin_domains" and any(v >= 0.5 for v in d.values()):
                raise ValueError("cop_margin_domains: a margin must be below 0.5 (of the foot length)")
            out[key] = d
        elif isinstance(cur, bool):
            if not isinstance(val, bool):
                raise ValueError(f"{key} must be true or false")
            out[key] = val
        elif isinstance(cur, (int, float)) or cur is None:
            if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val):
                raise ValueError(f"{key} must be a finite number")
            out[key] = float(val)
        elif isinstance(cur, str):
            if not isinstance(val, str):
                raise ValueError(f"{key} must be a string")
            allowed = {"backend": BACKENDS, "solver": tuple(SOLVERS)}.get(key)
            if allowed is not None and val not in allowed:
                raise ValueError(f"{key} must be one of {', '.join(allowed)}, not {val!r}")
            out[key] = val
        else:
            raise ValueError(f"{key!r} cannot be set from the command line")
    return out
