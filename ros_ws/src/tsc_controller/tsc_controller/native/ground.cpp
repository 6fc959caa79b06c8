// Compiled targets of the ground domains (tsc_controller._native.GroundTargets): what
// ground_targets.GroundTargets computes per tick in STANDING, LANDING and JUMPING before the QP, in one call —
// the feet's contact and anchors (update_feet), the pitch momentum's removal (_momentum_removal),
// the leg catch (_leg_catch, leg_catch) and the quintic blends of COM and pelvis from the state at
// the domain's entry to the standing targets (targets, quintic).  The same operations in
// the same order as those Python floats (built with -ffp-contract=off): the same numbers, checked on
// whole offline flips against the Python path (tests/unit/test_tsc_native.py).
//
// The entry anchors (values and rates at entry, targets, durations) stay computed by the Python
// side (once per domain entry) and are handed over with begin(); the results are written to buffers
// whose numpy views the controller's Desired objects hold (buffers()).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "terms.hpp"

namespace py = pybind11;
using namespace tsc_native;
using DArr = py::array_t<double, py::array::c_style | py::array::forcecast>;

namespace
{
  // Python's max(a, b) / min(a, b) of two floats: the first unless the second is larger / smaller
  inline double py_max(double a, double b) { return b > a ? b : a; }
  inline double py_min(double a, double b) { return b < a ? b : a; }

  /// profiles.quintic's coefficients at time s over T (T2 = T ** 2 as Python computes it).
  struct Quintic
  {
    bool done = false;               // T <= 0 or s >= T: the end value, zero rates
    double p = 0, dp = 0, ddp = 0, r = 0, dr = 0, ddr = 0, s0 = 0;

    Quintic(double T, double T2, double s)
    {
      if (T <= 0 || s >= T)
      {
        done = true;
        return;
      }
      s0 = py_max(s, 0.0);
      const double x = s0 / T, x2 = x * x, x3 = x2 * x;
      p = x3 * (10 - 15 * x + 6 * x2);
      dp = x2 * (30 - 60 * x + 30 * x2) / T;
      ddp = x * (60 - 180 * x + 120 * x2) / T2;
      r = x3 * (-6 + 8 * x - 3 * x2);
      dr = x2 * (-18 + 32 * x - 15 * x2) / T;
      ddr = x * (-36 + 96 * x - 60 * x2) / T2;
    }

    /// (y, ydot, yddot) of element i into out[0][i], out[1][i], out[2][i] (stride: the buffer's row)
    /// from y0 to y1 with the start rate v0 (quintic's element-by-element path).
    void blend(double y0, double y1, double v0, double T, double * out, long i, long stride) const
    {
      if (done)
      {
        out[i] = y1;
        out[stride + i] = 0.0;
        out[2 * stride + i] = 0.0;
        return;
      }
      const double c0 = s0 + T * r, c1 = 1.0 + T * dr, c2 = T * ddr, d = y1 - y0;
      out[i] = y0 + p * d + c0 * v0;
      out[stride + i] = dp * d + c1 * v0;
      out[2 * stride + i] = ddp * d + c2 * v0;
    }

    /// the same without a start rate (v0=None)
    void blend(double y0, double y1, double * out) const
    {
      if (done)
      {
        out[0] = y1;
        out[1] = 0.0;
        out[2] = 0.0;
        return;
      }
      const double d = y1 - y0;
      out[0] = y0 + p * d;
      out[1] = dp * d;
      out[2] = ddp * d;
    }
  };
} // namespace

class GroundTargets
{
public:
  /// feet: point-table rows of left toe, left heel, right toe, right heel; legs: of left foot, left
  /// hip, right foot, right hip; shin: q rows, stiffness, rest angle of the two shin springs; the
  /// ControllerConfig values the per-tick code reads (read once: the config is fixed once built).
  GroundTargets(std::vector<long> feet, std::vector<long> legs, std::vector<long> shin_q,
                std::vector<double> shin_k, std::vector<double> shin_q0, double mass, py::dict cfg)
    : feet_(std::move(feet)), legs_(std::move(legs)), shin_q_(std::move(shin_q)),
      shin_k_(std::move(shin_k)), shin_q0_(std::move(shin_q0)), mass_(mass)
  {
    if (feet_.size() != 4 || legs_.size() != 4 || shin_q_.size() != 2 || shin_k_.size() != 2 ||
        shin_q0_.size() != 2)
      throw std::invalid_argument("GroundTargets: 4 foot rows, 4 leg rows and 2 shin springs expected");
    auto f = [&](const char * k) { return cfg[k].cast<double>(); };
    per_foot_ = cfg["per_foot_contact"].cast<bool>();
    foot_lift_ = f("foot_lift");
    foot_land_ = f("foot_land");
    loaded_ = f("foot_loaded_spring");
    kp_ = f("kp");
    moment_ = f("landing_moment");
    moment_late_ = f("landing_moment_late");
    late_after_ = f("landing_late_after");
    ramp_ = f("moment_ramp");
    com_shift_ = f("com_shift");
    decel_ = f("catch_decel");
    L_min_ = f("L_min");
    slack_ = f("catch_slack");
    rise_ = f("rise_time");
    rise2_ = f("rise_time2");
    buf_.fill(0.0);
  }

  // ------------------------------------------------------------------ feet (update_feet)
  void reset_feet() { anchored_ = false; contact_ = {true, true}; }

  void update_feet(const TickTerms & tick)
  {
    const RowMat & P = tick.P;
    std::array<std::array<double, 6>, 2> p;
    for (int k = 0; k < 2; ++k)
      for (int e = 0; e < 2; ++e)
        for (int c = 0; c < 3; ++c)
          p[k][3 * e + c] = P(feet_[2 * k + e], c);
    const double z_low[2] = {py_min(p[0][2], p[0][5]), py_min(p[1][2], p[1][5])};
    if (!anchored_)
    {
      z_ground_ = py_min(z_low[0], z_low[1]);
      anchor_ = p;
      contact_ = {true, true};
      anchored_ = true;
    }
    double tau_shin[2];
    for (int k = 0; k < 2; ++k)
      tau_shin[k] = -shin_k_[k] * (tick.q[shin_q_[k]] - shin_q0_[k]);
    for (int k = 0; k < 2; ++k)
    {
      const double h = z_low[k] - z_ground_;
      if (contact_[k])
      {
        if (per_foot_ && h > foot_lift_ && tau_shin[k] < loaded_)
          contact_[k] = false;
        else
        {
          anchor_[k] = p[k];
          if (tau_shin[k] >= loaded_)
            z_ground_ += 0.01 * (z_low[k] - z_ground_);
        }
      }
      else if (h < foot_land_)
        contact_[k] = true;
    }
  }

  /// GroundTargets.standing_H_weight: the STANDING H_pitch weight w0 while the COM is over the span
  /// (along the feet's heading) of the feet on the ground, falling linearly past its front or back to
  /// edge_weight of w0 at `edge` beyond; w0 before the feet are anchored or with edge <= 0.
  double standing_H_weight(const TickTerms & tick, double w0, double edge, double edge_weight) const
  {
    if (edge <= 0.0 || !anchored_)
      return w0;
    const auto & a = anchor_;
    const double hx0 = (0.0 + (a[0][0] - a[0][3])) + (a[1][0] - a[1][3]);      // Python's sum()
    const double hy0 = (0.0 + (a[0][1] - a[0][4])) + (a[1][1] - a[1][4]);
    const double n = std::hypot(hx0, hy0);
    if (n < 1e-6)
      return w0;
    const double hx = hx0 / n, hy = hy0 / n;
    const bool any = contact_[0] || contact_[1];
    bool first = true;
    double front = 0.0, back = 0.0;
    for (int k = 0; k < 2; ++k)
    {
      if (any && !contact_[k])
        continue;
      const double f = hx * a[k][0] + hy * a[k][1], b = hx * a[k][3] + hy * a[k][4];
      front = first ? f : py_max(front, f);
      back = first ? b : py_min(back, b);
      first = false;
    }
    const double xi = hx * tick.com[0] + hy * tick.com[1];
    const double outside = py_max(xi - front, back - xi);
    const double f = py_min(1.0, py_max(1.0 - outside / edge, 0.0));
    return w0 * (edge_weight + (1.0 - edge_weight) * f);
  }

  py::tuple contact() const { return py::make_tuple(bool(contact_[0]), bool(contact_[1])); }
  py::object z_ground() const { return anchored_ ? py::object(py::float_(z_ground_)) : py::none(); }

  /// the toe, heel positions (6,) where foot k stands (or last stood), a copy; None before the first
  py::object anchor(int k) const
  {
    if (!anchored_)
      return py::none();
    if (k < 0 || k > 1)
      throw std::out_of_range("GroundTargets.anchor: foot 0 or 1");
    py::array_t<double> a(6);
    std::copy(anchor_[k].begin(), anchor_[k].end(), a.mutable_data());
    return a;
  }

  // ------------------------------------------------------------------ standing targets
  /// The anchors GroundTargets.targets takes at the domain's entry (blend over T, T2 = T ** 2).
  void begin(double t0, double L0, double Ld0, double L1, const DArr & c0, const DArr & cd0, const DArr & c1,
             const DArr & p0, const DArr & pd0, const DArr & p1, double T, double T2)
  {
    if (c0.size() != 2 || cd0.size() != 2 || c1.size() != 2 || p0.size() != 3 || pd0.size() != 3 ||
        p1.size() != 3)
      throw std::invalid_argument("GroundTargets.begin: COM (2,) and pelvis (3,) anchors expected");
    t0_ = tL_ = t0;
    L0_ = L0;
    Ld0_ = Ld0;
    L1_ = L1;
    for (int i = 0; i < 2; ++i)
      c0_[i] = c0.data()[i], cd0_[i] = cd0.data()[i], c1_[i] = c1.data()[i];
    for (int i = 0; i < 3; ++i)
      p0_[i] = p0.data()[i], pd0_[i] = pd0.data()[i], p1_[i] = p1.data()[i];
    T_ = T;
    T2_ = T2;
    H_now_ = 0.0;
  }

  /// One tick's desired values of H_pitch, L, COM x/y, pelvis roll/pitch/yaw into the buffers.
  void tick(const TickTerms & tick, double t, bool landing)
  {
    const double dt = t - t0_;
    momentum_removal(tick, dt);
    // COM: quintic from the entry, moved against the removal's CoP offset (LANDING), after the feet
    double * com = buf_.data() + COM;
    const Quintic qc(T_, T2_, dt);
    for (int i = 0; i < 2; ++i)
      qc.blend(c0_[i], c1_[i], cd0_[i], T_, com, i, 2);
    const double k = landing ? com_shift_ / (mass_ * 9.81) : 0.0;
    const double * H = buf_.data() + H_PITCH;
    com[0] += k * H[1];          // value of x by the removal's rate, its rate by the removal's acceleration
    com[2] += k * H[2];
    if (anchored_)
    {
      const auto &a0 = anchor_[0], &a1 = anchor_[1];
      for (int i = 0; i < 2; ++i)
      {
        const double mid = 0.25 * (a0[i] + a0[3 + i] + a1[i] + a1[3 + i]);
        com[i] += mid - c1_[i];
      }
    }
    leg_catch_tick(tick, t, landing);
    double * pel = buf_.data() + PELVIS;
    for (int i = 0; i < 3; ++i)
      qc.blend(p0_[i], p1_[i], pd0_[i], T_, pel, i, 3);
  }

  double H_now() const { return H_now_; }

  py::dict buffers(py::object self)
  {
    py::dict b;
    const py::ssize_t d = sizeof(double);
    auto view = [&](long at, py::ssize_t dim) {
      return py::array(py::dtype::of<double>(), {py::ssize_t(3), dim}, {dim * d, d}, buf_.data() + at, self);
    };
    b["H_pitch"] = view(H_PITCH, 1);
    b["L"] = view(LEG, 1);
    b["com"] = view(COM, 2);
    b["pelvis"] = view(PELVIS, 3);
    return b;
  }

private:
  // buffer layout: per output a 3 x dim block (value, rate, acceleration rows)
  static constexpr long H_PITCH = 0, LEG = 3, COM = 6, PELVIS = 12, N = 21;

  /// _momentum_removal: dH/dt = -clip(kp H, +-M), M ramped over moment_ramp (later to the late moment).
  void momentum_removal(const TickTerms & tick, double dt)
  {
    const double H_now = tick.hg[4];
    H_now_ = H_now;
    double M0 = 0.0, M1 = moment_, t1 = 0.0;
    if (moment_late_ != 0.0 && dt > late_after_)
      M0 = moment_, M1 = moment_late_, t1 = late_after_;
    const double x = ramp_ > 0 ? (dt - t1) / ramp_ : 1.0;
    const double M = M0 + (M1 - M0) * py_min(1.0, py_max(x, 0.0));
    const double slope = x < 1.0 ? (M1 - M0) / ramp_ : 0.0;
    double hd, hdd;
    if (kp_ * std::fabs(H_now) >= M)
    {
      hd = -std::copysign(M, H_now);
      hdd = -std::copysign(slope, H_now);
    }
    else
    {
      hd = -kp_ * H_now;
      hdd = 0.0;
    }
    double * H = buf_.data() + H_PITCH;
    H[0] = H_now;
    H[1] = hd;
    H[2] = hdd;
  }

  /// leg_catch(L0, v0, L1, t, decel, L_min, rise_time) into out[0..2]
  void leg_catch(double L0, double v0, double L1, double t, double * out) const
  {
    if (v0 >= 0.0)
    {
      Quintic(rise_, rise2_, t).blend(L0, L1, v0, rise_, out, 0, 1);
      return;
    }
    const double d = py_min(v0 * v0 / (2.0 * decel_), py_max(L0 - L_min_, 0.02));
    const double a = v0 * v0 / (2.0 * d);
    const double tc = -v0 / a;
    if (t < tc)
    {
      out[0] = L0 + v0 * t + 0.5 * a * t * t;
      out[1] = v0 + a * t;
      out[2] = a;
      return;
    }
    Quintic(rise_, rise2_, t - tc).blend(L0 - d, L1, out);
  }

  /// mean hip-to-foot distance of the two legs (outputs.LegLength's value)
  double leg_length(const TickTerms & tick) const
  {
    const RowMat & P = tick.P;
    double L = 0.0;
    for (int s = 0; s < 2; ++s)
    {
      const long f = legs_[2 * s], h = legs_[2 * s + 1];
      const double r0 = P(f, 0) - P(h, 0), r1 = P(f, 1) - P(h, 1), r2 = P(f, 2) - P(h, 2);
      L += std::sqrt(r0 * r0 + r1 * r1 + r2 * r2);
    }
    return 0.5 * L;
  }

  /// _leg_catch: the profile re-anchored on the measured state when the body sinks slower than it
  void leg_catch_tick(const TickTerms & tick, double t, bool landing)
  {
    double * out = buf_.data() + LEG;
    leg_catch(L0_, Ld0_, L1_, t - tL_, out);
    const double vz = tick.hg[2] / mass_;
    if (landing && vz < 0.0 && out[1] < vz - slack_)
    {
      L0_ = leg_length(tick);
      Ld0_ = vz;
      tL_ = t;
      leg_catch(L0_, vz, L1_, 0.0, out);
    }
  }

  std::vector<long> feet_, legs_, shin_q_;
  std::vector<double> shin_k_, shin_q0_;
  double mass_;
  bool per_foot_ = true;
  double foot_lift_ = 0, foot_land_ = 0, loaded_ = 0;
  double kp_ = 0, moment_ = 0, moment_late_ = 0, late_after_ = 0, ramp_ = 0, com_shift_ = 0;
  double decel_ = 0, L_min_ = 0, slack_ = 0, rise_ = 0, rise2_ = 0;
  // feet
  bool anchored_ = false;
  std::array<bool, 2> contact_{true, true};
  std::array<std::array<double, 6>, 2> anchor_{};
  double z_ground_ = 0.0;
  // standing anchors
  double t0_ = 0, tL_ = 0, L0_ = 0, Ld0_ = 0, L1_ = 0, T_ = 0, T2_ = 0, H_now_ = 0;
  std::array<double, 2> c0_{}, cd0_{}, c1_{};
  std::array<double, 3> p0_{}, pd0_{}, p1_{};
  std::array<double, N> buf_{};
};

void bind_ground(py::module_ & mod)
{
  py::class_<GroundTargets>(mod, "GroundTargets")
    .def(py::init<std::vector<long>, std::vector<long>, std::vector<long>, std::vector<double>,
                  std::vector<double>, double, py::dict>(),
         py::arg("feet"), py::arg("legs"), py::arg("shin_q"), py::arg("shin_k"), py::arg("shin_q0"),
         py::arg("mass"), py::arg("cfg"))
    .def("reset_feet", &GroundTargets::reset_feet)
    .def("update_feet", &GroundTargets::update_feet, py::arg("tick"))
    .def_property_readonly("contact", &GroundTargets::contact)
    .def_property_readonly("z_ground", &GroundTargets::z_ground)
    .def("anchor", &GroundTargets::anchor, py::arg("k"))
    .def("standing_H_weight", &GroundTargets::standing_H_weight, py::arg("tick"), py::arg("w0"), py::arg("edge"),
         py::arg("edge_weight"))
    .def("begin", &GroundTargets::begin, py::arg("t0"), py::arg("L0"), py::arg("Ld0"), py::arg("L1"),
         py::arg("c0"), py::arg("cd0"), py::arg("c1"), py::arg("p0"), py::arg("pd0"), py::arg("p1"),
         py::arg("T"), py::arg("T2"))
    .def("tick", &GroundTargets::tick, py::arg("tick"), py::arg("t"), py::arg("landing"))
    .def_property_readonly("H_now", &GroundTargets::H_now)
    .def(
      "buffers", [](py::object self) { return self.cast<GroundTargets &>().buffers(self); },
      "numpy views (3 x dim: value, rate, acceleration) of H_pitch, L, com, pelvis, rewritten by every tick");
}
