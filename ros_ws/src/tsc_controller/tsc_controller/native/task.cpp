// Compiled task rows of the TSC (tsc_controller._native.TaskRows): the outputs of outputs.py
// evaluated from a tick's terms (y, J, drift, ydot stacked), and the QP terms of tsc.TSC.solve
// (cost Hessian and gradient, GRF rows).  Formulas: outputs.py (each class's evaluate), tsc.py.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "task_kinds.hpp"
#include "terms.hpp"

namespace py = pybind11;
using namespace tsc_native;
using DArr = py::array_t<double, py::array::c_style | py::array::forcecast>;

/// The stacked outputs of one output list and the QP terms built on them.
class TaskRows
{
public:
  TaskRows(const py::list & specs, long nv, long nu, const DArr & kp, const DArr & kd)
  : nv_(nv)
  , nu_(nu)
  {
    long row = 0;
    for (auto h : specs)
    {
      auto t = h.cast<py::tuple>();
      Spec s{kind_of(t[0].cast<std::string>()), t[1].cast<std::vector<long>>(), t[2].cast<std::vector<double>>(),
             t[3].cast<long>(), row};
      row += s.dim;
      specs_.push_back(s);
    }
    m_ = row;
    if (kp.size() != m_ || kd.size() != m_)
      throw std::invalid_argument("tsc_native: gains of the wrong size");
    kp_ = Eigen::Map<const Vec>(kp.data(), m_);
    kd_ = Eigen::Map<const Vec>(kd.data(), m_);
    rhs_.setZero(m_);
    y_.setZero(m_);
    drift_.setZero(m_);
    ydot_.setZero(m_);
    J_.setZero(m_, nv_);
  }

  /// Evaluate every output at the tick's terms; `values` holds the values of PITCH outputs in order.
  void evaluate(const TickTerms & t, const std::vector<double> & values)
  {
    size_t iv = 0;
    J_.setZero();
    for (const auto & s : specs_)
    {
      switch (s.kind)
      {
      case CENTROIDAL:
        centroidal(t, s);
        break;
      case FLYWHEEL:
        flywheel(t, s);
        break;
      case LEG_LENGTH:
        leg_length(t, s);
        break;
      case LEG_ANGLE:
        leg_angle(t, s);
        break;
      case COM:
        com(t, s);
        break;
      case PELVIS:
        pelvis(t, s);
        break;
      case JOINTS:
        joints(t, s);
        break;
      case FOOT_PITCH:
        foot_pitch(t, s);
        break;
      case FOOT_POINTS:
        foot_points(t, s);
        break;
      case PITCH:
        pitch(t, s, values.at(iv++));
        break;
      case AXIS:
        axis(t, s);
        break;
      case JOINT_DIFFERENCES:
        joint_differences(t, s);
        break;
      }
    }
  }

  /// From the desired values (tsc.Desired per output, scalars broadcast over their output, missing
  /// derivatives 0): Y = y - value, and the rhs of eq. (Ydes) kept for qp,
  /// rhs = drift - (ff - kp Y - kd (ydot - d_value)), ff = d_value (degree 1) or dd_value (degree 2).
  /// Returns Y.  (tsc._Task.vectors / TSC._task_rows in numpy.)
  py::array_t<double> errors(const py::list & desired, const std::vector<bool> & deg1)
  {
    if (long(desired.size()) != long(specs_.size()) || deg1.size() != specs_.size())
      throw std::invalid_argument("tsc_native.errors: one desired value per output");
    py::array_t<double> ea(m_);
    Eigen::Map<Vec> e(ea.mutable_data(), m_);
    for (size_t j = 0; j < specs_.size(); ++j)
    {
      const Spec & s = specs_[j];
      py::handle d = desired[j];
      fill(d.attr("value"), s, val_);
      fill(d.attr("d_value"), s, dv_);
      fill(d.attr("dd_value"), s, ff_);
      const auto sl = Eigen::seqN(s.row, s.dim);
      if (deg1[j])
        ff_(sl) = dv_(sl);
    }
    e = y_ - val_;
    rhs_ = drift_ - (ff_ - kp_.cwiseProduct(e) - kd_.cwiseProduct(ydot_ - dv_));
    return ea;
  }

  /// G = J X, cA = G[:, :nu], cB = G[:, nu] + rhs (rhs of the last `errors`, or given); H = cA^T W cA + diag I, g = cA^T W cB - shift;
  /// with GRF rows Cg (over the first Cg.cols() constraint forces): C = -(Cg Y)[:, :nu],
  /// up = cg + (Cg Y)[:, nu].  Returns (H, g) or (H, g, C, up).
  py::tuple qp(const TickTerms & t, py::object rhs_obj, const DArr & w, double diag, py::object shift,
               py::object Cg_obj, py::object cg_obj)
  {
    const long m1 = nu_ + 1;
    if (w.size() != m_ || t.X.rows() != nv_ || t.X.cols() != m1)
      throw std::invalid_argument("tsc_native.qp: sizes do not match the task / the last elimination");
    if (!rhs_obj.is_none())
    {
      DArr rhs = rhs_obj.cast<DArr>();
      if (rhs.size() != m_)
        throw std::invalid_argument("tsc_native.qp: rhs of the wrong size");
      rhs_ = Eigen::Map<const Vec>(rhs.data(), m_);
    }
    G_.noalias() = J_ * t.X;
    Eigen::Map<const Vec> wv(w.data(), m_);
    G_.col(nu_) += rhs_;
    WA_ = wv.asDiagonal() * G_;   // W [cA, cB]
    py::array_t<double> Ha({nu_, nu_}), ga(nu_);
    Eigen::Map<RowMat> H(Ha.mutable_data(), nu_, nu_);
    Eigen::Map<Vec> g(ga.mutable_data(), nu_);
    H.noalias() = G_.leftCols(nu_).transpose() * WA_.leftCols(nu_);
    H.diagonal().array() += diag;
    g.noalias() = G_.leftCols(nu_).transpose() * WA_.col(nu_);
    if (!shift.is_none())
    {
      DArr sh = shift.cast<DArr>();
      g -= Eigen::Map<const Vec>(sh.data(), nu_);
    }
    if (Cg_obj.is_none())
      return py::make_tuple(Ha, ga);
    DArr Cg = Cg_obj.cast<DArr>(), cg = cg_obj.cast<DArr>();
    const long nr = Cg.shape(0), nf = Cg.shape(1);
    if (nf > t.Y.rows() || cg.size() != nr)
      throw std::invalid_argument("tsc_native.qp: GRF rows do not match the constraint forces");
    Eigen::Map<const RowMat> C0(Cg.data(), nr, nf);
    CY_.noalias() = C0 * t.Y.topRows(nf);
    py::array_t<double> Ca({nr, nu_}), upa(nr);
    Eigen::Map<RowMat>(Ca.mutable_data(), nr, nu_) = -CY_.leftCols(nu_);
    Eigen::Map<Vec>(upa.mutable_data(), nr) = Eigen::Map<const Vec>(cg.data(), nr) + CY_.col(nu_);
    return py::make_tuple(Ha, ga, Ca, upa);
  }

  py::dict buffers(py::object self)
  {
    py::dict b;
    auto view = [&](double * p, std::vector<py::ssize_t> shape, std::vector<py::ssize_t> strides) {
      return py::array(py::dtype::of<double>(), shape, strides, p, self);
    };
    const py::ssize_t d = sizeof(double);
    b["y"] = view(y_.data(), {m_}, {d});
    b["J"] = view(J_.data(), {m_, nv_}, {nv_ * d, d});
    b["drift"] = view(drift_.data(), {m_}, {d});
    b["ydot"] = view(ydot_.data(), {m_}, {d});
    return b;
  }

  long size() const { return m_; }

private:
  // one desired field of an output into rows s.row..: None -> 0, one value -> broadcast, else dim values
  void fill(py::handle x, const Spec & s, Vec & out)
  {
    if (out.size() != m_)
      out.setZero(m_);
    auto sl = out.segment(s.row, s.dim);
    if (x.is_none())
    {
      sl.setZero();
      return;
    }
    if (PyFloat_Check(x.ptr()))
    {
      sl.setConstant(PyFloat_AS_DOUBLE(x.ptr()));
      return;
    }
    DArr a = py::reinterpret_borrow<py::object>(x).cast<DArr>();
    if (a.size() == s.dim)
      sl = Eigen::Map<const Vec>(a.data(), s.dim);
    else if (a.size() == 1)
      sl.setConstant(a.data()[0]);
    else
      throw std::invalid_argument("tsc_native: a desired value of the wrong size");
  }

  // outputs.CentroidalPitchMomentum (degree 1: no ydot)
  void centroidal(const TickTerms & t, const Spec & s)
  {
    const long r = s.i[0];
    y_[s.row] = t.hg[r];
    J_.row(s.row) = t.Ag.row(r);
    drift_[s.row] = t.dAg_v[r];
    ydot_[s.row] = 0.0;
  }

  // outputs.FlywheelMomentum: i = (base v index, wheel v index), f = (I, a_x, a_y, a_z)
  void flywheel(const TickTerms & t, const Spec & s)
  {
    const long b = s.i[0], iv = s.i[1], row = s.row;
    const double I = s.f[0];
    const double a[3] = {s.f[1], s.f[2], s.f[3]};
    const double e[3] = {t.R_base(1, 0), t.R_base(1, 1), t.R_base(1, 2)};
    for (int k = 0; k < 3; ++k)
      J_(row, b + 3 + k) = I * e[k];
    J_(row, iv) = I * (e[0] * a[0] + e[1] * a[1] + e[2] * a[2]);
    const double w0 = t.v[b + 3], w1 = t.v[b + 4], w2 = t.v[b + 5], qd = t.v[iv];
    const double a0 = a[0] * qd, a1 = a[1] * qd, a2 = a[2] * qd;
    drift_[row] = I * (e[0] * (w1 * a2 - w2 * a1) + e[1] * (w2 * a0 - w0 * a2) + e[2] * (w0 * a1 - w1 * a0));
    y_[row] = J_.row(row).dot(t.v);
    ydot_[row] = 0.0;
  }

  // J row += coef * (row `3 k + axis` of the point Jacobians)
  void add_point_row(long row, long k, int axis, double coef, const TickTerms & t)
  {
    J_.row(row) += coef * t.pt_rows.row(3 * k + axis).head(nv_);
  }

  // outputs.LegLength: i = (foot, hip) point pairs
  void leg_length(const TickTerms & t, const Spec & s)
  {
    const long np = long(s.i.size()) / 2, row = s.row;
    const double k = 1.0 / double(np);
    double L = 0.0, Ld = 0.0, dd = 0.0;
    for (long j = 0; j < np; ++j)
    {
      const long f = s.i[2 * j], h = s.i[2 * j + 1];
      double r[3], vr[3], ar[3];
      for (int c = 0; c < 3; ++c)
      {
        r[c] = t.P(f, c) - t.P(h, c);
        vr[c] = t.pdot(f, c) - t.pdot(h, c);
        ar[c] = t.pt_rows(3 * f + c, nv_) - t.pt_rows(3 * h + c, nv_);
      }
      const double Li = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
      const double n[3] = {r[0] / Li, r[1] / Li, r[2] / Li};
      const double Ldi = n[0] * vr[0] + n[1] * vr[1] + n[2] * vr[2];
      dd += n[0] * ar[0] + n[1] * ar[1] + n[2] * ar[2]
            + (vr[0] * vr[0] + vr[1] * vr[1] + vr[2] * vr[2] - Ldi * Ldi) / Li;
      L += Li;
      Ld += Ldi;
      for (int c = 0; c < 3; ++c)
      {
        add_point_row(row, f, c, k * n[c], t);
        add_point_row(row, h, c, -k * n[c], t);
      }
    }
    y_[row] = k * L;
    drift_[row] = k * dd;
    ydot_[row] = k * Ld;
  }

  // outputs.LegAngle: i = (foot, hip) point pairs
  void leg_angle(const TickTerms & t, const Spec & s)
  {
    const long np = long(s.i.size()) / 2, row = s.row;
    const double k = 1.0 / double(np);
    double beta = 0.0, bdot = 0.0, drift = 0.0;
    for (long j = 0; j < np; ++j)
    {
      const long f = s.i[2 * j], h = s.i[2 * j + 1];
      // (x, z) = hip->foot, z measured downwards
      const Atan2Rates r = atan2_rates(t.P(f, 0) - t.P(h, 0), -(t.P(f, 2) - t.P(h, 2)),
                                       t.pdot(f, 0) - t.pdot(h, 0), -(t.pdot(f, 2) - t.pdot(h, 2)));
      const double ax = t.pt_rows(3 * f, nv_) - t.pt_rows(3 * h, nv_);
      const double az = t.pt_rows(3 * f + 2, nv_) - t.pt_rows(3 * h + 2, nv_);
      beta += r.angle;
      bdot += r.rate;
      drift += r.gu * ax - r.gw * az + r.curv;
      add_point_row(row, f, 0, k * r.gu, t);
      add_point_row(row, f, 2, -k * r.gw, t);
      add_point_row(row, h, 0, -k * r.gu, t);
      add_point_row(row, h, 2, k * r.gw, t);
    }
    y_[row] = k * beta;
    drift_[row] = k * drift;
    ydot_[row] = k * bdot;
  }

  // outputs.ComPosition: i = axes
  void com(const TickTerms & t, const Spec & s)
  {
    const double im = 1.0 / t.mass;
    for (size_t j = 0; j < s.i.size(); ++j)
    {
      const long a = s.i[j], row = s.row + long(j);
      y_[row] = t.com[a];
      J_.row(row) = t.Ag.row(a) * im;
      drift_[row] = t.dAg_v[a] * im;
      ydot_[row] = t.hg[a] * im;
    }
  }

  // outputs.PelvisOrientation: i = (base v index, axes...), ZYX Euler angles
  void pelvis(const TickTerms & t, const Spec & s)
  {
    const long b = s.i[0];
    const auto & R = t.R_base;
    const double x = t.v[b + 3], y = t.v[b + 4], z = t.v[b + 5];
    const double w0 = R(0, 0) * x + R(0, 1) * y + R(0, 2) * z;
    const double w1 = R(1, 0) * x + R(1, 1) * y + R(1, 2) * z;
    const double w2 = R(2, 0) * x + R(2, 1) * y + R(2, 2) * z;
    const double psi = std::atan2(R(1, 0), R(0, 0));
    const double th = std::asin(std::max(-1.0, std::min(1.0, -R(2, 0))));
    const double phi = std::atan2(R(2, 1), R(2, 2));
    const double cp = std::cos(psi), sp = std::sin(psi), ct = std::cos(th), st = std::sin(th);
    const double g = cp * w0 + sp * w1, hh = -sp * w0 + cp * w1;
    const double thd = hh, phid = g / ct, psid = w2 + st * phid;
    const double d_th = -psid * g;
    const double d_phi = psid * hh / ct + g * st * thd / (ct * ct);
    const double d_psi = ct * thd * phid + st * d_phi;
    const double E[3][3] = {{cp / ct, sp / ct, 0.0}, {-sp, cp, 0.0}, {st * cp / ct, st * sp / ct, 1.0}};
    const double ang[3] = {phi, th, psi}, vel[3] = {phid, thd, psid}, dr[3] = {d_phi, d_th, d_psi};
    for (size_t j = 1; j < s.i.size(); ++j)
    {
      const long a = s.i[j], row = s.row + long(j) - 1;
      for (int c = 0; c < 3; ++c)
        J_(row, b + 3 + c) = E[a][0] * R(0, c) + E[a][1] * R(1, c) + E[a][2] * R(2, c);
      y_[row] = ang[a];
      ydot_[row] = vel[a];
      drift_[row] = dr[a];
    }
  }

  // outputs.JointPositions: i = (q index, v index) pairs
  void joints(const TickTerms & t, const Spec & s)
  {
    for (long j = 0; j < s.dim; ++j)
    {
      const long row = s.row + j;
      y_[row] = t.q[s.i[2 * j]];
      J_(row, s.i[2 * j + 1]) = 1.0;
      drift_[row] = 0.0;
      ydot_[row] = t.v[s.i[2 * j + 1]];
    }
  }

  // outputs.LegAsymmetry: i = (q, v index of the left joint, q, v index of the right one) per row;
  // y = q_l - q_r, J = e_l - e_r, drift 0
  void joint_differences(const TickTerms & t, const Spec & s)
  {
    for (long j = 0; j < s.dim; ++j)
    {
      const long row = s.row + j;
      const long ql = s.i[4 * j], vl = s.i[4 * j + 1], qr = s.i[4 * j + 2], vr = s.i[4 * j + 3];
      y_[row] = t.q[ql] - t.q[qr];
      J_(row, vl) = 1.0;
      J_(row, vr) = -1.0;
      drift_[row] = 0.0;
      ydot_[row] = t.v[vl] - t.v[vr];
    }
  }

  // outputs.FootPitch: i = (toe, heel) point pairs; atan2(z_toe - z_heel, x_toe - x_heel)
  void foot_pitch(const TickTerms & t, const Spec & s)
  {
    const long np = long(s.i.size()) / 2, row = s.row;
    const double k = 1.0 / double(np);
    double y = 0.0, drift = 0.0, vel = 0.0;
    for (long j = 0; j < np; ++j)
    {
      const long to = s.i[2 * j], he = s.i[2 * j + 1];
      // (rise, run) of the heel->toe line
      const Atan2Rates r = atan2_rates(t.P(to, 2) - t.P(he, 2), t.P(to, 0) - t.P(he, 0),
                                       t.pdot(to, 2) - t.pdot(he, 2), t.pdot(to, 0) - t.pdot(he, 0));
      const double az = t.pt_rows(3 * to + 2, nv_) - t.pt_rows(3 * he + 2, nv_);
      const double ax = t.pt_rows(3 * to, nv_) - t.pt_rows(3 * he, nv_);
      y += r.angle;
      vel += r.rate;
      drift += r.gu * az + r.gw * ax + r.curv;
      add_point_row(row, to, 0, k * r.gw, t);
      add_point_row(row, to, 2, k * r.gu, t);
      add_point_row(row, he, 0, -k * r.gw, t);
      add_point_row(row, he, 2, -k * r.gu, t);
    }
    y_[row] = k * y;
    drift_[row] = k * drift;
    ydot_[row] = k * vel;
  }

  // outputs.FootPoints: i = (toe, heel)
  void foot_points(const TickTerms & t, const Spec & s)
  {
    for (long j = 0; j < 2; ++j)
      for (int c = 0; c < 3; ++c)
      {
        const long k = s.i[j], row = s.row + 3 * j + c;
        y_[row] = t.P(k, c);
        J_.row(row) = t.pt_rows.row(3 * k + c).head(nv_);
        drift_[row] = t.pt_rows(3 * k + c, nv_);
        ydot_[row] = t.pdot(k, c);
      }
  }

  // outputs.SagittalPitch: i = (base v index); the value comes from the controller
  void pitch(const TickTerms & t, const Spec & s, double value)
  {
    const long b = s.i[0], row = s.row;
    for (int c = 0; c < 3; ++c)
      J_(row, b + 3 + c) = t.R_base(1, c);
    y_[row] = value;
    drift_[row] = 0.0;
    ydot_[row] = J_.row(row).dot(t.v);
  }

  // outputs.PelvisAxisTilt: i = (base v index); world x, z of r = R e_y, ydot = w x r,
  // drift = w x (w x r), J = rows x, z of -[r]x R (w = R omega_local, world)
  void axis(const TickTerms & t, const Spec & s)
  {
    const long b = s.i[0];
    const auto & R = t.R_base;
    const double r[3] = {R(0, 1), R(1, 1), R(2, 1)};
    double w[3];
    for (int c = 0; c < 3; ++c)
      w[c] = R(c, 0) * t.v[b + 3] + R(c, 1) * t.v[b + 4] + R(c, 2) * t.v[b + 5];
    const double yd[3] = {w[1] * r[2] - w[2] * r[1], w[2] * r[0] - w[0] * r[2], w[0] * r[1] - w[1] * r[0]};
    const double dr[3] = {w[1] * yd[2] - w[2] * yd[1], w[2] * yd[0] - w[0] * yd[2], w[0] * yd[1] - w[1] * yd[0]};
    const double m[2][3] = {{0.0, r[2], -r[1]}, {r[1], -r[0], 0.0}};   // rows x, z of -[r]x
    const int comp[2] = {0, 2};
    for (int j = 0; j < 2; ++j)
    {
      const long row = s.row + j;
      for (int c = 0; c < 3; ++c)
        J_(row, b + 3 + c) = m[j][0] * R(0, c) + m[j][1] * R(1, c) + m[j][2] * R(2, c);
      y_[row] = r[comp[j]];
      ydot_[row] = yd[comp[j]];
      drift_[row] = dr[comp[j]];
    }
  }

  long nv_, nu_, m_ = 0;
  std::vector<Spec> specs_;
  Vec y_, drift_, ydot_, kp_, kd_, rhs_, val_, dv_, ff_;
  RowMat J_, G_, WA_, CY_;
};

void bind_task(py::module_ & mod)
{
  py::class_<TickTerms>(mod, "TickTerms");
  py::class_<TaskRows>(mod, "TaskRows")
    .def(py::init<const py::list &, long, long, const DArr &, const DArr &>(), py::arg("specs"), py::arg("nv"),
         py::arg("nu"), py::arg("kp"), py::arg("kd"))
    .def("evaluate", &TaskRows::evaluate, py::arg("tick"), py::arg("values"))
    .def("errors", &TaskRows::errors, py::arg("desired"), py::arg("deg1"))
    .def("qp", &TaskRows::qp, py::arg("tick"), py::arg("rhs"), py::arg("w"), py::arg("diag"), py::arg("shift"),
         py::arg("Cg"), py::arg("cg"))
    .def("__len__", &TaskRows::size)
    .def(
      "buffers", [](py::object self) { return self.cast<TaskRows &>().buffers(self); },
      "numpy views of y, J, drift, ydot (rewritten by every evaluate)");
}
