"""tsc_node's hold for the planner's reference at a contact event, driven in-process (no graph): its
message handlers fed a standing robot's serialized states, a jumping plan, a LIFT_OFF and the flight's
reference in the order that the two topics may take; prints which steps were answered after each, as JSON.
Run by tests/graph/test_tsc_node_reference_hold.py in the domain it claims."""
import json
import sys

import rclpy
from flip_msgs.msg import ContactEvent, FlipReference
from flip_transport.lockstep import RawMessage, joint_state_layout, ns_to_stamp, odometry_layout
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from cassie_flip_sim.simulator import Simulator
from cassie_model.model import export_mjcf
from tsc_controller import tsc_node as T

DT = T.DT_NS


def reference(domain, start_ns, names, n=11, span=0.3, params=None):
    m = FlipReference(plan_id=1, domain=domain)
    ns_to_stamp(start_ns, m.start_time)
    m.t = [span * i / (n - 1) for i in range(n)]
    m.output_names = list(names)
    vals = {"H_pitch": 0.0, "L": 0.9, "x_com": 0.0, "phi_pitch": 0.0}
    m.value = [vals[k] for _ in range(n) for k in names]
    m.d_value = [0.0] * len(m.value)
    m.dd_value = [0.0] * len(m.value)
    m.parameter_names = list((params or {}).keys())
    m.parameter_values = [float(v) for v in (params or {}).values()]
    return m


def main(hold: bool, timeout_s: float | None) -> dict:
    rclpy.init()
    node = T.TscNode()
    node.hold_for_reference = hold
    if timeout_s is not None:
        T.REFERENCE_HOLD_TIMEOUT_S = timeout_s
    sim = Simulator()
    node._on_message('/robot_description_mjcf', String(data=export_mjcf(sim.flywheel)))
    answered = []
    node._publish_command = lambda k_ns: answered.append(k_ns // DT)
    node.matched = True
    n = len(sim.joint_names)
    js = RawMessage(JointState(name=list(sim.joint_names), position=[0.0] * n, velocity=[0.0] * n,
                               effort=[0.0] * n), joint_state_layout)
    od = RawMessage(Odometry(child_frame_id="pelvis"), odometry_layout)

    def state(k):
        f, o = js.fields, od.fields
        sim.state_into(f["position"], f["velocity"], f["effort"], o["pose"], o["twist"])
        js.stamp(k * DT)
        od.stamp(k * DT)
        node._on_state(js.data(), od.data())
        return list(answered)

    out = {}
    node._on_message('/fslip/reference', reference(FlipReference.DOMAIN_JUMPING, 2 * DT,
                                                   ["H_pitch", "L", "x_com", "phi_pitch"]))
    out["standing"] = [state(k) for k in range(3)][-1]
    ev = ContactEvent(step=3, event=ContactEvent.LIFT_OFF, domain=ContactEvent.DOMAIN_FLIGHT)
    ns_to_stamp(3 * DT, ev.header.stamp)
    node._on_message('/contact_events', ev)
    out["event_step"] = state(3)
    if timeout_s is not None:
        import time
        time.sleep(2 * timeout_s)
    out["sent_again"] = state(3)                  # the simulator sends an unanswered state again
    out["held"] = node.state_held
    node._on_message('/fslip/reference', reference(FlipReference.DOMAIN_FLIGHT, 3 * DT, ["phi_pitch", "L"],
                                                   params={"T1": 0.2, "flight_time": 0.3}))
    out["after_reference"] = state(3)             # the node's loop answers the held state
    out["next"] = state(4)
    node.node.destroy_node()
    rclpy.shutdown()
    return out


if __name__ == "__main__":
    hold = sys.argv[1] == "hold"
    timeout = float(sys.argv[2]) if len(sys.argv) > 2 else None
    print(json.dumps(main(hold, timeout)))
