"""Write a synthetic rosbag2 (MCAP) of a flip with rosbags only (no ROS): /clock, /odom,
/joint_states (flywheel), /motor_command, /contact_events, /fslip/reference — the topics and
types of docs/architecture.md, so summary/plots can be tested without a simulator."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer

from flip_tools.typestore import flip_typestore

G = 9.81
MOTORS = ["left_hip_roll", "left_hip_yaw", "left_hip_pitch", "left_knee", "left_foot",
          "right_hip_roll", "right_hip_yaw", "right_hip_pitch", "right_knee", "right_foot", "flywheel"]


def trajectory(rotation_deg=360.0, final_z=0.9, final_tilt_deg=0.0, flight_time=0.6, distance=0.4,
               z0=1.0, dt=0.001, t_stand=1.0, t_rest=1.5, flight_yaw_deg=0.0):
    """Pelvis x, z, pitch (rad, about +y) and yaw (rad, about world z: 0 until lift-off, ramps to
    ``flight_yaw_deg`` at touch-down, then stays) sampled every dt. Returns dict of arrays + event times."""
    rot = math.radians(rotation_deg)
    extra = math.radians(final_tilt_deg)
    t_lo = t_stand + 0.3
    t_td = t_lo + flight_time
    t_end = t_td + 0.4 + t_rest
    t = np.arange(0.0, t_end + 1e-12, dt)
    x, z, th = np.zeros_like(t), np.full_like(t, z0), np.zeros_like(t)
    crouch = (t >= t_stand) & (t < t_lo)
    z[crouch] = z0 - 0.1 * np.sin(np.pi * (t[crouch] - t_stand) / 0.3)
    fl = (t >= t_lo) & (t < t_td)
    tau = t[fl] - t_lo
    s = tau / flight_time
    x[fl] = distance * s
    z[fl] = z0 + (G * flight_time / 2) * tau - G * tau ** 2 / 2
    th[fl] = rot * (3 * s ** 2 - 2 * s ** 3)
    land = t >= t_td
    s = np.clip((t[land] - t_td) / 0.4, 0, 1)
    w = 0.5 - 0.5 * np.cos(np.pi * s)
    x[land] = distance
    z[land] = z0 + (final_z - z0) * w
    th[land] = rot + extra * w
    yaw = math.radians(flight_yaw_deg) * np.clip((t - t_lo) / flight_time, 0.0, 1.0)
    return {"t": t, "x": x, "z": z, "th": th, "yaw": yaw, "t_lo": t_lo, "t_td": t_td, "flight_time": flight_time,
            "rot": rot}


def write_flip_bag(path: str | Path, contact_events: bool = True, body_contact_at: float | None = None,
                   resent_tail: int = 0, resent_head: int = 0, drop_joint_states=(), jumping_turns=(),
                   **kw) -> dict:
    """Write the bag; returns the trajectory that was written. `contact_events=False` leaves
    /contact_events out; `body_contact_at=T` adds a BODY_CONTACT event (left_knee) at sim time T;
    `resent_tail=N` adds N copies of the last /odom, 50 ms of wall time apart, after the last step
    (what a lockstep simulator re-sends while its stopped controller does not answer);
    `resent_head=N`: the first /odom sent N more times, 50 ms apart, before the copy the controller
    answered (a controller not yet answering at the start);
    `drop_joint_states` = sample indices whose /joint_states is left out (-1: the last);
    `jumping_turns` = one JUMPING /fslip/reference per entry (plan ids 1, 2, ...) whose ``turn``
    parameter is that entry (rad): the flips the planner started."""
    tr = trajectory(**kw)
    store = flip_typestore()
    T = store.types
    Time = T["builtin_interfaces/msg/Time"]
    Header = T["std_msgs/msg/Header"]
    V3, P, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
    Pose, Twist = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/Twist"]
    PwC, TwC = T["geometry_msgs/msg/PoseWithCovariance"], T["geometry_msgs/msg/TwistWithCovariance"]
    Odom, Clock, JS = T["nav_msgs/msg/Odometry"], T["rosgraph_msgs/msg/Clock"], T["sensor_msgs/msg/JointState"]
    MC, CE, FR = (T["flip_msgs/msg/MotorCommand"], T["flip_msgs/msg/ContactEvent"],
                  T["flip_msgs/msg/FlipReference"])

    def stamp(sec):
        ns = int(round(sec * 1e9))
        return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    t, x, z, th = tr["t"], tr["x"], tr["z"], tr["th"]
    dropped = {k % len(t) for k in drop_joint_states}
    dt = t[1] - t[0]
    vx, vz, wy = np.gradient(x, dt), np.gradient(z, dt), np.gradient(th, dt)
    yaw = tr["yaw"]
    wz = np.gradient(yaw, dt)
    wall0 = 1_700_000_000_000_000_000
    rtf = 0.5  # sim runs at half real time: wall = sim / 0.5
    path = Path(path)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        c_clock = w.add_connection("/clock", "rosgraph_msgs/msg/Clock", typestore=store)
        c_odom = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        c_js = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        c_mc = w.add_connection("/motor_command", "flip_msgs/msg/MotorCommand", typestore=store)
        c_ce = (w.add_connection("/contact_events", "flip_msgs/msg/ContactEvent", typestore=store)
                if contact_events else None)
        c_fr = w.add_connection("/fslip/reference", "flip_msgs/msg/FlipReference", typestore=store)

        def put(conn, sim_t, msg, typ):
            w.write(conn, wall0 + int(sim_t / rtf * 1e9), store.serialize_cdr(msg, typ))

        ref = FR(header=Header(stamp=stamp(0.9), frame_id=""), plan_id=1, domain=2, start_time=stamp(tr["t_lo"]),
                 t=np.linspace(0, tr["flight_time"], 5), output_names=["H_pitch", "phi_pitch"],
                 value=np.array([v for s in np.linspace(0, 1, 5) for v in (30.0, tr["rot"] * s)]),
                 d_value=np.zeros(10), dd_value=np.zeros(10), parameter_names=["T1"],
                 parameter_values=np.array([0.3]), liftoff_zdot=G * tr["flight_time"] / 2, liftoff_xdot=0.6,
                 flight_time=tr["flight_time"], rotation_to_go=tr["rot"], peak_flywheel_speed=250.0,
                 solve_time=0.42, iterations=17)
        put(c_fr, 0.9, ref, "flip_msgs/msg/FlipReference")
        for i, turn in enumerate(jumping_turns):
            jref = FR(header=Header(stamp=stamp(0.5 + 0.01 * i), frame_id=""), plan_id=i + 1, domain=1,
                      start_time=stamp(1.0), t=np.linspace(0, 0.3, 3), output_names=["L"], value=np.full(3, 0.9),
                      d_value=np.zeros(3), dd_value=np.zeros(3), parameter_names=["x_start", "turn"],
                      parameter_values=np.array([0.0, float(turn)]), liftoff_zdot=G * tr["flight_time"] / 2,
                      liftoff_xdot=0.6, flight_time=tr["flight_time"], rotation_to_go=float(turn),
                      peak_flywheel_speed=250.0, solve_time=0.1, iterations=20)
            put(c_fr, 0.5 + 0.01 * i, jref, "flip_msgs/msg/FlipReference")
        events = [(tr["t_lo"], 0, 2), (tr["t_td"], 1, 3)] if contact_events else []
        if body_contact_at is not None:
            events.append((body_contact_at, CE.BODY_CONTACT, 3))
        for k in range(len(t)):
            hdr = Header(stamp=stamp(t[k]), frame_id="world")
            put(c_clock, t[k], Clock(clock=stamp(t[k])), "rosgraph_msgs/msg/Clock")
            # orientation R = Rz(yaw) Ry(th); twist in the pelvis frame (R^T of the world vectors)
            cy, sy, ch, sh = math.cos(yaw[k] / 2), math.sin(yaw[k] / 2), math.cos(th[k] / 2), math.sin(th[k] / 2)
            pose = Pose(position=P(x=x[k], y=0.0, z=z[k]), orientation=Q(x=-sy * sh, y=cy * sh, z=sy * ch, w=cy * ch))
            c, s_, cz, sz = math.cos(th[k]), math.sin(th[k]), math.cos(yaw[k]), math.sin(yaw[k])
            R = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
                [[c, 0.0, s_], [0.0, 1.0, 0.0], [-s_, 0.0, c]])
            lin_b = R.T @ np.array([vx[k], 0.0, vz[k]])
            ang_b = R.T @ (np.array([-sz * wy[k], cz * wy[k], wz[k]]))
            od = Odom(header=hdr, child_frame_id="pelvis", pose=PwC(pose=pose, covariance=np.zeros(36)),
                      twist=TwC(twist=Twist(linear=V3(x=lin_b[0], y=lin_b[1], z=lin_b[2]),
                                            angular=V3(x=ang_b[0], y=ang_b[1], z=ang_b[2])),
                                covariance=np.zeros(36)))
            if k == 0:
                for j in range(resent_head, 0, -1):
                    w.write(c_odom, wall0 + int(t[k] / rtf * 1e9) - j * 50_000_000,
                            store.serialize_cdr(od, "nav_msgs/msg/Odometry"))
            put(c_odom, t[k], od, "nav_msgs/msg/Odometry")
            if k == len(t) - 1:
                for j in range(1, resent_tail + 1):
                    w.write(c_odom, wall0 + int(t[k] / rtf * 1e9) + j * 50_000_000,
                            store.serialize_cdr(od, "nav_msgs/msg/Odometry"))
            fw_speed = -20.0 * wy[k]
            if k not in dropped:
                put(c_js, t[k], JS(header=hdr, name=["left_knee", "flywheel"], position=np.array([-1.2, 0.0]),
                                   velocity=np.array([0.0, fw_speed]), effort=np.array([3.0, -2.0 * wy[k]])),
                    "sensor_msgs/msg/JointState")
            eff = np.array([1.0 * i for i in range(10)] + [-2.0 * wy[k]])
            put(c_mc, t[k], MC(header=hdr, step=k, name=MOTORS, effort=eff,
                               compute_time_us=np.float32(100.0 + (k % 100))), "flip_msgs/msg/MotorCommand")
            for (te, ev, dom) in events:
                if abs(t[k] - te) < dt / 2:
                    hdr_e = Header(stamp=hdr.stamp, frame_id="left_knee" if ev == CE.BODY_CONTACT else "world")
                    put(c_ce, t[k], CE(header=hdr_e, step=k, event=ev, domain=dom, pelvis_pose=pose,
                                       pelvis_twist=Twist(linear=V3(x=vx[k], y=0.0, z=vz[k]),
                                                          angular=V3(x=0.0, y=wy[k], z=0.0)),
                                       com_position=P(x=x[k], y=0.0, z=z[k] - 0.1),
                                       com_velocity=V3(x=vx[k], y=0.0, z=vz[k]),
                                       centroidal_pitch_momentum=30.0, left_normal_force=0.0 if ev == 0 else 500.0,
                                       right_normal_force=0.0 if ev == 0 else 480.0,
                                       # the feet 0.2 m ahead of the COM (the COM sits at x, as above)
                                       support_center=P(x=x[k] + 0.2, y=0.0, z=0.02)), "flip_msgs/msg/ContactEvent")
    return tr
