// cassie_flip_sim._native: the simulator's per-step work in C++ on the MuJoCo C API, on the mjModel /
// mjData of the Python bindings (their addresses).  Simulator.step and sim_node's state messages run
// here: at 2 kHz, the same work in numpy and Python cost the simulator's process ~90 us of CPU a step
// in the node graph (scripts/bench_graph.py), where it shares one CPU with the controller.
//
// Same arithmetic, in the same order, as the numpy reference (Simulator(backend="python")): the
// torque clip of motor_limits.MotorLimits.clip, contacts.FootForces, foot_wrench.FootWrenches (the
// same MuJoCo functions in the same order), Simulator's accessors.  Built with -ffp-contract=off (no
// fused multiply-adds numpy does not make).
//
// Stepper._api() hands the same step, state and body-contact test to sim_node's compiled stepping
// loop (flip_transport._rcl_io.SimLoop) as a C table of function pointers (flip_transport's
// native/stepper_api.h); Detector is that loop's copy of contacts.ContactDetector, exposed here for
// its test against the Python one.
#include "motor_envelope.h"
#include "stepper_api.h"

#include <mujoco/mujoco.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <stdexcept>
#include <vector>

namespace py = pybind11;
using DArr = py::array_t<double, py::array::c_style | py::array::forcecast>;
using IArr = py::array_t<long, py::array::c_style | py::array::forcecast>;

namespace {
std::vector<long> ivec(const IArr & a) { return std::vector<long>(a.data(), a.data() + a.size()); }
std::vector<double> dvec(const DArr & a) { return std::vector<double>(a.data(), a.data() + a.size()); }
/// An output array as bytes: float64, contiguous, writeable, n long; it may be unaligned (sim_node
/// passes numpy views of a serialized message, whose float64 fields sit 4 bytes off an 8-byte
/// boundary), so it is written with memcpy.
unsigned char * out_ptr(py::array & a, long n, const char * what)
{
  if (!a.dtype().is(py::dtype::of<double>()) || a.size() != n || !a.writeable() ||
      !(a.flags() & py::array::c_style))
    throw std::invalid_argument(std::string("Stepper: ") + what +
                                ": needs a writeable contiguous float64 array of the right size");
  return static_cast<unsigned char *>(a.mutable_data());
}
inline void put(unsigned char * a, long i, double v) { std::memcpy(a + 8 * i, &v, 8); }
}  // namespace

class Stepper {
public:
  /// model, data: mjModel* / mjData* addresses (mujoco.MjModel._address, MjData._address; the
  /// Python objects must outlive this).  Motors: dof and actuator ids, torque limits, 1/no-load speed
  /// (0: no speed limit); foot_side: per geom 0 (left foot), 1 (right foot) or -1; joint table of
  /// Simulator.joint_names: qpos (-1: part of a ball) and qvel addresses, per ball joint its qpos
  /// address and its first entry; body_geom: per geom 1 for a body other than the feet; foot_body:
  /// the left and right foot bodies (whose frames the wrenches are in).
  Stepper(std::uintptr_t model, std::uintptr_t data, IArr motor_dof, IArr act_ids, DArr torque_limit,
          DArr inv_w0, IArr foot_side, IArr jq, IArr jv, IArr ball_qadr, IArr ball_entry,
          long pelvis, IArr body_geom, IArr foot_body)
  : m_(reinterpret_cast<const mjModel *>(model)), d_(reinterpret_cast<mjData *>(data)),
    dof_(ivec(motor_dof)), act_(ivec(act_ids)), lim_(dvec(torque_limit)), inv_w0_(dvec(inv_w0)),
    side_(ivec(foot_side)), jq_(ivec(jq)), jv_(ivec(jv)), bq_(ivec(ball_qadr)),
    be_(ivec(ball_entry)), pelvis_(pelvis), body_(ivec(body_geom)), foot_body_(ivec(foot_body))
  {
    const size_t nu = dof_.size();
    if (act_.size() != nu || lim_.size() != nu || inv_w0_.size() != nu)
      throw std::invalid_argument("Stepper: motor tables of different sizes");
    if (long(side_.size()) != m_->ngeom || long(body_.size()) != m_->ngeom)
      throw std::invalid_argument("Stepper: foot_side and body_geom need one entry per geom");
    bool ok = jq_.size() == jv_.size() && bq_.size() == be_.size() && pelvis_ >= 0 && pelvis_ < m_->nbody &&
              foot_body_.size() == 2;
    for (size_t k = 0; ok && k < foot_body_.size(); ++k) ok = foot_body_[k] >= 0 && foot_body_[k] < m_->nbody;
    for (size_t i = 0; ok && i < nu; ++i) ok = dof_[i] >= 0 && dof_[i] < m_->nv && act_[i] >= 0 && act_[i] < m_->nu;
    for (size_t i = 0; ok && i < jq_.size(); ++i) ok = jq_[i] < m_->nq && jv_[i] >= 0 && jv_[i] < m_->nv;
    for (size_t b = 0; ok && b < bq_.size(); ++b)
      ok = bq_[b] >= 0 && bq_[b] + 4 <= m_->nq && be_[b] >= 0 && be_[b] + 3 <= long(jv_.size());
    if (!ok) throw std::invalid_argument("Stepper: motor or joint table, pelvis or feet, out of the model's range");
  }

  /// One step with joint-side torques u: clipped to the torque-speed envelope (when clip), written
  /// to ctrl, mj_step2, the feet's normal forces summed over their contacts (mj_contactForce), then
  /// mj_step1 of the new state.  u_out gets the applied torques; wrench (12 float64, or None), when
  /// given, the feet's wrenches of the state stepped from (foot_wrench.FootWrenches, left then
  /// right).  Returns (left, right) forces.
  py::tuple step(DArr u, py::array u_out, bool clip, py::object wrench)
  {
    const long n = long(dof_.size());
    if (u.size() != n) throw std::invalid_argument("Stepper.step: u of the wrong size");
    double out[2], w[12];
    unsigned char * wo = nullptr;
    if (!wrench.is_none()) {
      py::array wa = wrench.cast<py::array>();
      wo = out_ptr(wa, 12, "wrench");
    }
    step_raw(u.data(), out_ptr(u_out, n, "u_out"), clip, out, wo ? w : nullptr);
    if (wo) std::memcpy(wo, w, sizeof w);
    return py::make_tuple(out[0], out[1]);
  }

  /// step on raw arrays (u: n motors; uo: n float64, maybe unaligned; out: the feet's forces;
  /// wrench: nullptr, or 12 doubles for the feet's wrenches)
  void step_raw(const double * ui, unsigned char * uo, bool clip, double out[2], double * wrench)
  {
    const long n = long(dof_.size());
    for (long i = 0; i < n; ++i) {
      double v = ui[i];
      if (clip) {
        // MotorLimits.bounds: |u| <= limit * available_fraction (the published curve, motor_envelope.h)
        const double avail = lim_[i] * cassie_model::available_fraction(d_->qvel[dof_[i]], inv_w0_[i]);
        v = std::min(std::max(v, -avail), avail);
      }
      put(uo, i, v);
      d_->ctrl[act_[i]] = v;
    }
    mj_step2(m_, d_);
    mjtNum f[6];
    out[0] = out[1] = 0.0;
    for (int i = 0; i < d_->ncon; ++i) {
      const mjContact & c = d_->contact[i];
      long s = side_[c.geom[0]];
      if (s < 0) s = side_[c.geom[1]];
      if (s < 0 || c.efc_address < 0) continue;
      mj_contactForce(m_, d_, i, f);
      out[s] += f[0];
    }
    if (wrench) foot_wrenches(wrench);
    mj_step1(m_, d_);
  }

  /// foot_wrench.FootWrenches on the data as it is (between mj_step2 and mj_step1): per foot (left,
  /// right) force and moment about its origin, in its frame, into w[0..6), w[6..12)
  void foot_wrenches(double * w) const
  {
    mjtNum sum[2][6] = {}, f6[6], F[3], T[3], r[3], rxF[3];
    for (int i = 0; i < d_->ncon; ++i) {
      const mjContact & c = d_->contact[i];
      long s = side_[c.geom[1]];                 // the normal points from geom1 to geom2: force on geom2
      bool flip = false;
      if (s < 0) {
        s = side_[c.geom[0]];
        flip = true;
      }
      if (s < 0 || c.efc_address < 0) continue;
      mj_contactForce(m_, d_, i, f6);
      mju_mulMatTVec3(F, c.frame, f6);
      mju_mulMatTVec3(T, c.frame, f6 + 3);
      if (flip) {
        mju_scl3(F, F, -1.0);
        mju_scl3(T, T, -1.0);
      }
      mju_sub3(r, c.pos, d_->xpos + 3 * foot_body_[s]);
      mju_cross(rxF, r, F);
      mju_addTo3(sum[s], F);
      mju_addTo3(sum[s] + 3, rxF);
      mju_addTo3(sum[s] + 3, T);
    }
    for (int k = 0; k < 2; ++k)
      for (int a = 0; a < 6; a += 3) mju_mulMatTVec3(w + 6 * k + a, d_->xmat + 9 * foot_body_[k], sum[k] + a);
  }

  /// The state as sim_node publishes it: per joint_names entry the position (hinge: qpos; ball: its
  /// rotation vector, mju_quat2Vel), velocity and effort (qfrc_actuator + qfrc_spring); the pelvis
  /// pose (x, y, z, quaternion x, y, z, w) and twist in the pelvis frame (R^T v, local angular
  /// velocity; REP 105).
  void state(py::array pos, py::array vel, py::array eff, py::array pose, py::array twist) const
  {
    const long n = long(jv_.size());
    unsigned char * p = out_ptr(pos, n, "pos"), * v = out_ptr(vel, n, "vel"), * e = out_ptr(eff, n, "eff");
    unsigned char * ps = out_ptr(pose, 7, "pose"), * tw = out_ptr(twist, 6, "twist");
    state_raw(p, v, e, ps, tw);
  }

  /// state into raw float64 fields (maybe unaligned) of the sizes state() checks
  void state_raw(unsigned char * p, unsigned char * v, unsigned char * e, unsigned char * ps,
                 unsigned char * tw) const
  {
    const long n = long(jv_.size());
    for (long i = 0; i < n; ++i) {
      put(p, i, d_->qpos[jq_[i] < 0 ? 0 : jq_[i]]);
      put(v, i, d_->qvel[jv_[i]]);
      put(e, i, d_->qfrc_actuator[jv_[i]] + d_->qfrc_spring[jv_[i]]);
    }
    for (size_t b = 0; b < bq_.size(); ++b) {
      mjtNum rv[3];
      mju_quat2Vel(rv, d_->qpos + bq_[b], 1.0);
      for (int k = 0; k < 3; ++k) put(p, be_[b] + k, rv[k]);
    }
    const mjtNum * q = d_->qpos, * qv = d_->qvel;
    const int order[7] = {0, 1, 2, 4, 5, 6, 3};      // x y z, then the quaternion x y z w (MuJoCo: w x y z)
    for (int i = 0; i < 7; ++i) put(ps, i, q[order[i]]);
    const mjtNum * R = d_->xmat + 9 * pelvis_;      // row-major, body to world
    for (int i = 0; i < 3; ++i) put(tw, i, R[i] * qv[0] + R[3 + i] * qv[1] + R[6 + i] * qv[2]);
    for (int i = 3; i < 6; ++i) put(tw, i, qv[i]);
  }

  /// Whether a geom of a body other than the feet is in a contact now.
  bool body_contact() const
  {
    for (int i = 0; i < d_->ncon; ++i)
      if (body_[d_->contact[i].geom[0]] || body_[d_->contact[i].geom[1]]) return true;
    return false;
  }

  /// The C table of stepper_api.h in a capsule, which holds a reference to this Stepper's Python
  /// object (so the table stays valid while the capsule lives).
  py::object api(py::object self)
  {
    api_.version = CFS_STEPPER_API_VERSION;
    api_.self = this;
    api_.time = [](void * s) -> double { return static_cast<Stepper *>(s)->d_->time; };
    api_.step = [](void * s, const double * u, unsigned char * uo, int clip, double f[2], double * w) {
      static_cast<Stepper *>(s)->step_raw(u, uo, clip != 0, f, w);
    };
    api_.state = [](void * s, unsigned char * p, unsigned char * v, unsigned char * e, unsigned char * ps,
                    unsigned char * tw) { static_cast<Stepper *>(s)->state_raw(p, v, e, ps, tw); };
    api_.body_contact = [](void * s) -> int { return static_cast<Stepper *>(s)->body_contact() ? 1 : 0; };
    api_.n_motors = long(dof_.size());
    api_.n_joints = long(jv_.size());
    PyObject * cap = PyCapsule_New(&api_, CFS_STEPPER_API_CAPSULE, [](PyObject * c) {
      Py_XDECREF(static_cast<PyObject *>(PyCapsule_GetContext(c)));
    });
    if (!cap) throw py::error_already_set();
    Py_INCREF(self.ptr());
    PyCapsule_SetContext(cap, self.ptr());
    return py::reinterpret_steal<py::object>(cap);
  }

private:
  CfsStepperApi api_{};
  const mjModel * m_;
  mjData * d_;
  std::vector<long> dof_, act_;
  std::vector<double> lim_, inv_w0_;
  std::vector<long> side_;
  std::vector<long> jq_, jv_, bq_, be_;
  long pelvis_;
  std::vector<long> body_;
  std::vector<long> foot_body_;
};

PYBIND11_MODULE(_native, mod)
{
  mod.doc() = "cassie_flip_sim's per-step work on the MuJoCo C API (see native/step.cpp)";
  py::class_<Stepper>(mod, "Stepper")
    .def(py::init<std::uintptr_t, std::uintptr_t, IArr, IArr, DArr, DArr, IArr, IArr, IArr, IArr, IArr,
                  long, IArr, IArr>(),
         py::arg("model"), py::arg("data"), py::arg("motor_dof"), py::arg("act_ids"), py::arg("torque_limit"),
         py::arg("inv_w0"), py::arg("foot_side"), py::arg("jq"), py::arg("jv"),
         py::arg("ball_qadr"), py::arg("ball_entry"), py::arg("pelvis"), py::arg("body_geom"),
         py::arg("foot_body"))
    .def("step", &Stepper::step, py::arg("u"), py::arg("u_out"), py::arg("clip"), py::arg("wrench") = py::none())
    .def("state", &Stepper::state, py::arg("pos"), py::arg("vel"), py::arg("eff"), py::arg("pose"), py::arg("twist"))
    .def("body_contact", &Stepper::body_contact)
    .def("_api", [](py::object self) { return self.cast<Stepper &>().api(self); },
         "the C table of stepper_api.h in a capsule (for _rcl_io.SimLoop)");
  // contacts.ContactDetector's C++ copy, as SimLoop runs it (for the test against the Python one)
  py::class_<CfsDetector>(mod, "Detector")
    .def(py::init([](double lift_off_force, double touch_down_force, long lift_off_steps, long min_flight_steps) {
           CfsDetector d;
           d.lift_off_force = lift_off_force;
           d.touch_down_force = touch_down_force;
           d.lift_off_steps = lift_off_steps;
           d.min_flight_steps = min_flight_steps;
           return d;
         }), py::arg("lift_off_force"), py::arg("touch_down_force"), py::arg("lift_off_steps"),
         py::arg("min_flight_steps"))
    .def_readwrite("in_contact", &CfsDetector::in_contact)
    .def_readwrite("zero_run", &CfsDetector::zero_run)
    .def_readwrite("onset_step", &CfsDetector::onset_step)
    .def_readwrite("onset_time", &CfsDetector::onset_time)
    .def_readwrite("flight_steps", &CfsDetector::flight_steps)
    .def("update", [](CfsDetector & d, long step, double time, double left, double right) -> py::object {
           CfsEvent ev;
           if (!cfs_detector_update(d, step, time, left, right, &ev)) return py::none();
           return py::make_tuple(ev.kind, ev.step, ev.time, ev.detected_step, ev.left_force, ev.right_force);
         }, py::arg("step"), py::arg("time"), py::arg("left_force"), py::arg("right_force"),
         "ContactDetector.update: None, or (kind, step, time, detected_step, left_force, right_force)");
}
