// Compiled per-tick terms of the TSC (tsc_controller._native): what dynamics.Dynamics.update,
// _point_table, _constraint_rows and tsc.ConstrainedDynamics compute in numpy, in one call.
//
// The Pinocchio model and data are the Python side's own objects (pin.Model / pin.Data, reached
// by reference through boost.python as pinocchio/bindings/python/pybind11.hpp does), so the tick
// runs on the model dynamics.py built (MJCF import, added point frames) and leaves data (oMi, oMf,
// J, Ag, com, ...) exactly as the numpy path does.  The index tables (points, supports, constraint
// row map T) come from dynamics.py as well; see its module doc for the formulas.
#include <pinocchio/fwd.hpp>

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/centroidal.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>

#include <boost/python.hpp>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "terms.hpp"

namespace py = pybind11;
namespace bp = boost::python;
using namespace tsc_native;

using Model = pinocchio::Model;
using Data = pinocchio::Data;
using Vec3 = Eigen::Vector3d;
using DArr = py::array_t<double, py::array::c_style | py::array::forcecast>;
using IArr = py::array_t<long, py::array::c_style | py::array::forcecast>;

namespace
{
  template<typename T>
  T & from_boost(py::handle h, const char * what)
  {
    bp::extract<T &> ex(h.ptr());
    if (!ex.check())
      throw std::invalid_argument(std::string("tsc_native: not a pinocchio ") + what);
    return ex();
  }

  RowMat to_mat(const DArr & a, Eigen::Index rows, Eigen::Index cols)
  {
    if (a.size() != rows * cols)
      throw std::invalid_argument("tsc_native: table of unexpected size");
    return Eigen::Map<const RowMat>(a.data(), rows, cols);
  }

  std::vector<long> to_idx(const IArr & a)
  {
    return std::vector<long>(a.data(), a.data() + a.size());
  }

  // numpy view of a row-major buffer owned by the Tick (kept alive by `base`)
  py::array view(double * p, std::vector<py::ssize_t> shape, py::handle base)
  {
    std::vector<py::ssize_t> strides(shape.size());
    py::ssize_t s = sizeof(double);
    for (size_t i = shape.size(); i-- > 0;)
    {
      strides[i] = s;
      s *= shape[i];
    }
    return py::array(py::dtype::of<double>(), shape, strides, p, base);
  }
} // namespace

void bind_task(py::module_ & mod);
void bind_limits(py::module_ & mod);
void bind_state(py::module_ & mod);
void bind_ground(py::module_ & mod);

/// One tick's rigid-body terms, point table, constraint rows and constrained dynamics.
class Tick : public TickTerms
{
public:
  Tick(py::object model, py::object data, py::dict t)
  : model_obj_(model)
  , data_obj_(data)
  , model_(from_boost<Model>(model, "Model"))
  , data_(from_boost<Data>(data, "Data"))
  {
    const auto & m = model_;
    nv = nv_ = m.nv;
    nq = nq_ = m.nq;
    mass = t["mass"].cast<double>();
    if (t["nq"].cast<long>() != nq_ || t["nv"].cast<long>() != nv_
        || t["njoints"].cast<long>() != m.njoints || t["nframes"].cast<long>() != m.nframes)
      throw std::runtime_error("tsc_native: the model seen from C++ differs from Python's (ABI)");
    motor_v_ = to_idx(t["motor_v"].cast<IArr>());
    nu = nu_ = long(motor_v_.size());
    neg_D_ = Eigen::Map<const Vec>(t["neg_D"].cast<DArr>().data(), nv_);
    q_spring_ = Eigen::Map<const Vec>(t["q_spring"].cast<DArr>().data(), nq_);
    spring_v_ = to_idx(t["spring_v"].cast<IArr>());
    spring_q_ = to_idx(t["spring_q"].cast<IArr>());
    {
      DArr k = t["spring_k"].cast<DArr>();
      spring_k_.assign(k.data(), k.data() + k.size());
    }
    base_jid_ = t["base_jid"].cast<long>();

    // points
    pt_joint_ = to_idx(t["pt_joint"].cast<IArr>());
    n = n_ = long(pt_joint_.size());
    pt_local_ = to_mat(t["pt_local"].cast<DArr>(), n_, 3);
    S_ = to_mat(t["pt_support"].cast<DArr>(), nv_, n_);
    Sw_ = to_mat(t["pt_support_w"].cast<DArr>(), nv_, 2 * n_);
    pt_sup_.resize(n_);
    for (long k = 0; k < n_; ++k)
      for (long i = 0; i < nv_; ++i)
        if (S_(i, k) != 0.0)
          pt_sup_[k].push_back(i);

    // constraint rows
    T_ = t["T"].cast<DArr>().size() ? to_mat(t["T"].cast<DArr>(), t["nr"].cast<long>(), 3 * n_) : RowMat();
    nr_ = T_.rows();
    cs_idx_ = to_idx(t["cs_idx"].cast<IArr>());
    contact_idx_ = to_idx(t["contact_idx"].cast<IArr>());
    n_blk_ = t["loop_S"].cast<DArr>().size() / 9;
    loop_S_ = to_mat(t["loop_S"].cast<DArr>(), n_blk_ * 3, 3);
    loop_take_ = to_idx(t["loop_take"].cast<IArr>());
    loop_put_ = to_idx(t["loop_put"].cast<IArr>());
    loop_joint_ = to_idx(t["loop_joint"].cast<IArr>());
    spring_Jd_ = to_mat(t["spring_Jd"].cast<DArr>(), t["n_spring_rows"].cast<long>(), nv_ + 1);
    // sparsity of T: its constant entries and the per-tick ones
    std::vector<std::vector<char>> nz(nr_, std::vector<char>(3 * n_, 0));
    for (long r = 0; r < nr_; ++r)
      for (long c = 0; c < 3 * n_; ++c)
        nz[r][c] = T_(r, c) != 0.0;
    for (long i : cs_idx_)
      nz[i / (3 * n_)][i % (3 * n_)] = 1;
    for (long i : loop_put_)
      nz[i / (3 * n_)][i % (3 * n_)] = 1;
    T_nz_.resize(nr_);
    for (long r = 0; r < nr_; ++r)
      for (long c = 0; c < 3 * n_; ++c)
        if (nz[r][c])
          T_nz_[r].push_back(c);
    py::list sets = t["row_sets"];
    for (auto s : sets)
      row_sets_.push_back(to_idx(s.cast<IArr>()));
    allocate_buffers();
  }

  /// All terms of one tick from (q, v); see dynamics.Dynamics.update.
  void update(const DArr & q_in, const DArr & v_in)
  {
    if (q_in.size() != nq_ || v_in.size() != nv_)
      throw std::invalid_argument("tsc_native.update: q or v of the wrong size");
    q = Eigen::Map<const Vec>(q_in.data(), nq_);
    v = Eigen::Map<const Vec>(v_in.data(), nv_);
    const Model & m = model_;
    Data & d = data_;

    pinocchio::computeMinverse(m, d, q);
    Minv_.triangularView<Eigen::Upper>() = d.Minv.triangularView<Eigen::Upper>();
    Minv_.triangularView<Eigen::StrictlyLower>() = d.Minv.transpose().triangularView<Eigen::StrictlyLower>();
    d.Minv = Minv_;   // as the Python binding leaves it: full symmetric
    const auto & h = pinocchio::nonLinearEffects(m, d, q, v);
    tau_p_ = neg_D_.cwiseProduct(v);
    for (size_t i = 0; i < spring_v_.size(); ++i)
      tau_p_[spring_v_[i]] += -spring_k_[i] * (q[spring_q_[i]] - q_spring_[spring_q_[i]]);
    BH_.col(nu_) = tau_p_ - h;

    pinocchio::dccrba(m, d, q, v);
    Ag_ = d.Ag;
    dAg_v_.noalias() = d.dAg * v;
    hg_.noalias() = d.Ag * v;
    com_ = d.com[0];
    R_base_ = d.oMi[base_jid_].rotation();
    pinocchio::updateFramePlacements(m, d);

    point_table(v);
    constraint_rows();
  }

  /// Y = (J M^-1 J^T)^-1 (J M^-1 [B, -H] + [0, Jdot v]) and X = M^-1 [B, -H] - M^-1 J^T Y for the
  /// constraint rows of row set `sel`; (ok, Y, X, J, Jdot v), ok false when J M^-1 J^T is not positive
  /// definite.  Fresh arrays (a QPResult keeps them past the tick).
  py::tuple eliminate(long sel)
  {
    const long nc = long(row_sets_.at(sel).size()), m1 = nu_ + 1;
    const bool ok = eliminate_in_place(sel);
    py::array_t<double> Ya({nc, m1}), Xa({nv_, m1}), Ja({nc, nv_}), dJva(nc);
    Eigen::Map<RowMat>(Ja.mutable_data(), nc, nv_) = J_;
    Eigen::Map<Vec>(dJva.mutable_data(), nc) = dJv_;
    if (!ok)
      return py::make_tuple(false, Ya, Xa, Ja, dJva);
    Eigen::Map<RowMat>(Ya.mutable_data(), nc, m1) = Y;
    Eigen::Map<RowMat>(Xa.mutable_data(), nv_, m1) = X;
    return py::make_tuple(true, Ya, Xa, Ja, dJva);
  }

  /// `eliminate` without the arrays: Y and X stay here for the task's `qp` (the controller node's
  /// call, which asks for no predicted forces); false when J M^-1 J^T is not positive definite.
  bool eliminate_in_place(long sel)
  {
    const auto & rs = row_sets_.at(sel);
    const long nc = long(rs.size()), m1 = nu_ + 1;
    J_.resize(nc, nv_);
    dJv_.resize(nc);
    for (long i = 0; i < nc; ++i)
    {
      J_.row(i) = rows_.row(rs[i]).head(nv_);
      dJv_[i] = rows_(rs[i], nv_);
    }
    // M^-1 J^T, M^-1 [B, -H] (columns of M^-1, M^-1 (-H)); M^-1 is symmetric
    MiJt_.noalias() = Minv_ * J_.transpose();
    MiBH_.resize(nv_, m1);
    for (long i = 0; i < nu_; ++i)
      MiBH_.col(i) = Minv_.row(motor_v_[i]).transpose();
    MiBH_.col(nu_).noalias() = Minv_ * BH_.col(nu_);
    // J M^-1 J^T and J M^-1 [B, -H] + [0, Jdot v]
    JMiJt_.noalias() = J_ * MiJt_;
    rhs_.noalias() = J_ * MiBH_;
    rhs_.col(nu_) += dJv_;
    llt_.compute(JMiJt_);
    if (llt_.info() != Eigen::Success)
      return false;
    Y = llt_.solve(rhs_);
    X = MiBH_;
    X.noalias() -= MiJt_ * Y;
    return true;
  }

  /// numpy views of the tick's buffers (valid for the Tick's life, rewritten by every update)
  py::dict buffers(py::object self)
  {
    py::dict b;
    const long n = n_, nv = nv_;
    b["Minv"] = view(Minv_.data(), {nv, nv}, self);
    b["BH"] = view(BH_.data(), {nv, nu_ + 1}, self);
    b["tau_passive"] = view(tau_p_.data(), {nv}, self);
    b["Ag"] = view(Ag_.data(), {6, nv}, self);
    b["dAg_v"] = view(dAg_v_.data(), {6}, self);
    b["hg"] = view(hg_.data(), {6}, self);
    b["com"] = view(com_.data(), {3}, self);
    b["R_base"] = view(R_base_.data(), {3, 3}, self);
    b["P"] = view(P_.data(), {n, 3}, self);
    b["pdot"] = view(pdot_.data(), {n, 3}, self);
    b["omega"] = view(omega_.data(), {n, 3}, self);
    b["pt_rows"] = view(pt_rows_.data(), {3 * n, nv + 1}, self);
    b["rows"] = view(rows_.data(), {long(rows_.rows()), nv + 1}, self);
    return b;
  }

private:
  // the per-tick buffers, zeroed, in their sizes; the constant rows of the springs in place
  void allocate_buffers()
  {
    q.setZero(nq_);
    v.setZero(nv_);
    Minv_.setZero(nv_, nv_);
    BH_.setZero(nv_, nu_ + 1);
    for (long i = 0; i < nu_; ++i)
      BH_(motor_v_[i], i) = 1.0;
    tau_p_.setZero(nv_);
    Ag_.setZero(6, nv_);
    dAg_v_.setZero(6);
    hg_.setZero(6);
    com_.setZero(3);
    R_base_.setZero();
    P_.setZero(n_, 3);
    pdot_.setZero(n_, 3);
    omega_.setZero(n_, 3);
    pt_rows_.setZero(3 * n_, nv_ + 1);
    rows_.setZero(nr_ + spring_Jd_.rows(), nv_ + 1);
    rows_.bottomRows(spring_Jd_.rows()) = spring_Jd_;
    Sv_.resize(nv_, n_);
    Swv_.resize(nv_, 2 * n_);
    blk_.resize(n_blk_ * 3, 3);
  }

  // positions, Jacobians, drifts, velocities of the points (dynamics.py module doc)
  void point_table(const Eigen::Ref<const Vec> & v)
  {
    const Data & d = data_;
    const long nv = nv_;
    Sv_ = S_.array().colwise() * v.array();
    Swv_ = Sw_.array().colwise() * v.array();
    acc_.noalias() = d.dJ * Sv_;                    // (a_O, alpha) per point
    w_.noalias() = d.J.bottomRows<3>() * Swv_;       // omega, omega - omega_1
    for (long k = 0; k < n_; ++k)
    {
      const auto & M = d.oMi[pt_joint_[k]];
      const Vec3 p = M.rotation() * pt_local_.row(k).transpose() + M.translation();
      P_.row(k) = p;
      auto Jp = pt_rows_.middleRows<3>(3 * k);
      Jp.leftCols(nv).setZero();
      Vec3 pd = Vec3::Zero();
      for (long i : pt_sup_[k])
      {
        const Vec3 c = d.J.col(i).head<3>() - p.cross(d.J.col(i).tail<3>());
        Jp.col(i) = c;
        pd += c * v[i];
      }
      pdot_.row(k) = pd;
      omega_.row(k) = w_.col(k);
      const Vec3 a = acc_.col(k).head<3>() - p.cross(acc_.col(k).tail<3>()) - pd.cross(Vec3(w_.col(n_ + k)));
      Jp.col(nv) = a;
    }
  }

  // [J, Jdot v] of all constraint rows: T (foot headings, loops' S R1^T) times the point rows
  void constraint_rows()
  {
    const long w = 3 * n_;
    double * Tf = T_.data();
    for (long f = 0; f < long(contact_idx_.size()) / 2; ++f)
    {
      const long toe = contact_idx_[2 * f], heel = contact_idx_[2 * f + 1];
      const double dx = P_(toe, 0) - P_(heel, 0), dy = P_(toe, 1) - P_(heel, 1);
      const double nrm = std::sqrt(dx * dx + dy * dy);
      const double c = dx / nrm, s = dy / nrm;
      const double cs[6] = {c, s, -s, c, -s, c};
      for (int i = 0; i < 6; ++i)
        Tf[cs_idx_[6 * f + i]] = cs[i];
    }
    for (long b = 0; b < n_blk_; ++b)
      blk_.middleRows<3>(3 * b) = loop_S_.middleRows<3>(3 * b) * data_.oMi[loop_joint_[b]].rotation().transpose();
    for (size_t i = 0; i < loop_take_.size(); ++i)
      Tf[loop_put_[i]] = blk_.data()[loop_take_[i]];
    for (long r = 0; r < nr_; ++r)
    {
      auto row = rows_.row(r);
      row.setZero();
      for (long c : T_nz_[r])
        row += Tf[r * w + c] * pt_rows_.row(c);
    }
  }

  py::object model_obj_, data_obj_;   // keep the Python objects (and so model_, data_) alive
  const Model & model_;
  Data & data_;
  long nq_, nv_, nu_, n_, nr_, n_blk_, base_jid_;
  std::vector<long> motor_v_, spring_v_, spring_q_, pt_joint_, cs_idx_, contact_idx_;
  std::vector<long> loop_take_, loop_put_, loop_joint_;
  std::vector<double> spring_k_;
  std::vector<std::vector<long>> pt_sup_, T_nz_, row_sets_;
  Vec neg_D_, q_spring_;
  RowMat pt_local_, S_, Sw_, T_, loop_S_, spring_Jd_;
  // per tick (TickTerms' buffers under this file's names)
  RowMat &Minv_ = Minv, &BH_ = BH, &Ag_ = Ag, &P_ = P, &pdot_ = pdot, &omega_ = omega, &pt_rows_ = pt_rows,
         &rows_ = rows;
  Vec &tau_p_ = tau_p, &dAg_v_ = dAg_v, &hg_ = hg, &com_ = com;
  RowMat3 & R_base_ = R_base;
  RowMat blk_;
  Eigen::MatrixXd Sv_, Swv_, acc_, w_;
  // elimination scratch
  Eigen::MatrixXd J_, MiJt_, MiBH_, JMiJt_, rhs_;
  Vec dJv_;
  Eigen::LLT<Eigen::MatrixXd> llt_;
};

PYBIND11_MODULE(_native, mod)
{
  mod.doc() = "Compiled per-tick terms of the TSC (see tsc_controller.dynamics, backend='native').";
  bind_task(mod);
  bind_limits(mod);
  bind_state(mod);
  bind_ground(mod);
  py::class_<Tick, TickTerms>(mod, "Tick")
    .def(py::init<py::object, py::object, py::dict>(), py::arg("model"), py::arg("data"), py::arg("tables"))
    .def("update", &Tick::update, py::arg("q"), py::arg("v"))
    .def("eliminate", &Tick::eliminate, py::arg("row_set"))
    .def("eliminate_in_place", &Tick::eliminate_in_place, py::arg("row_set"))
    .def(
      "buffers", [](py::object self) { return self.cast<Tick &>().buffers(self); },
      "numpy views of the tick's buffers");
}
