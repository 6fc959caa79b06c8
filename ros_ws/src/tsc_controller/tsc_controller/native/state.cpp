// Compiled state conversion (tsc_controller._native.StateMap): what state.StateConverter.from_ros
// computes in numpy and Pinocchio's Python bindings, in one call: hinge positions and velocities
// copied into (q, v), each ball joint's rotation vector r turned into its quaternion by
// pinocchio::exp3 and Eigen's quaternion from a rotation matrix (the functions pin.exp3 and
// pin.Quaternion call), the floating base's pose and twist set.  The base quaternion comes
// normalised: numpy's norm is BLAS's dot, whose rounding a loop here does not reproduce.
#include <pinocchio/fwd.hpp>

#include <pinocchio/spatial.hpp>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Geometry>
#include <stdexcept>
#include <vector>

namespace py = pybind11;
using DArr = py::array_t<double, py::array::c_style | py::array::forcecast>;
using IArr = py::array_t<long, py::array::c_style | py::array::forcecast>;

namespace
{
  std::vector<long> idx(const IArr & a)
  {
    return std::vector<long>(a.data(), a.data() + a.size());
  }

  const double * vec(const DArr & a, py::ssize_t n, const char * what)
  {
    if (a.size() != n)
      throw std::invalid_argument(std::string("StateMap: ") + what + " of the wrong size");
    return a.data();
  }
}  // namespace

class StateMap
{
public:
  /// (q, v) sizes, the base's first q and v index; hinges: q[hq] = position[hs], v[hv] = velocity[hs];
  /// balls: per ball its q and v index and the three entries (x, y, z) of its rotation vector.
  StateMap(long nq, long nv, long base_q, long base_v, long n_in, IArr hq, IArr hv, IArr hs, IArr ball_q,
           IArr ball_v, IArr ball_k)
  : nq_(nq), nv_(nv), bq_(base_q), bv_(base_v), n_in_(n_in), hq_(idx(hq)), hv_(idx(hv)), hs_(idx(hs)),
    ballq_(idx(ball_q)), ballv_(idx(ball_v)), ballk_(idx(ball_k))
  {
    bool ok = hq_.size() == hv_.size() && hq_.size() == hs_.size() && ballq_.size() == ballv_.size()
              && ballk_.size() == 3 * ballq_.size() && bq_ >= 0 && bq_ + 7 <= nq_ && bv_ >= 0 && bv_ + 6 <= nv_;
    for (size_t i = 0; ok && i < hq_.size(); ++i)
      ok = hq_[i] >= 0 && hq_[i] < nq_ && hv_[i] >= 0 && hv_[i] < nv_ && hs_[i] >= 0 && hs_[i] < n_in_;
    for (size_t b = 0; ok && b < ballq_.size(); ++b)
      ok = ballq_[b] >= 0 && ballq_[b] + 4 <= nq_ && ballv_[b] >= 0 && ballv_[b] + 3 <= nv_;
    for (size_t i = 0; ok && i < ballk_.size(); ++i)
      ok = ballk_[i] >= 0 && ballk_[i] < n_in_;
    if (!ok)
      throw std::invalid_argument("StateMap: index table out of range");
  }

  /// (q, v) from the JointState arrays and the Odometry pose (position, unit quaternion x y z w) and
  /// twist (linear, angular; child frame).
  py::tuple convert(const DArr & position, const DArr & velocity, const DArr & base_position,
                    const DArr & base_quat_xyzw, const DArr & lin, const DArr & ang) const
  {
    const double * p = vec(position, n_in_, "position"), * w = vec(velocity, n_in_, "velocity");
    const double * bp = vec(base_position, 3, "base position"), * bqt = vec(base_quat_xyzw, 4, "base quaternion");
    const double * l = vec(lin, 3, "linear velocity"), * a = vec(ang, 3, "angular velocity");
    py::array_t<double> qa(nq_), va(nv_);
    double * q = qa.mutable_data(), * v = va.mutable_data();
    for (int i = 0; i < 3; ++i)
      q[bq_ + i] = bp[i];
    for (int i = 0; i < 4; ++i)
      q[bq_ + 3 + i] = bqt[i];
    for (int i = 0; i < 3; ++i)
    {
      v[bv_ + i] = l[i];
      v[bv_ + 3 + i] = a[i];
    }
    for (size_t i = 0; i < hq_.size(); ++i)
    {
      q[hq_[i]] = p[hs_[i]];
      v[hv_[i]] = w[hs_[i]];
    }
    for (size_t b = 0; b < ballq_.size(); ++b)
    {
      const Eigen::Vector3d r(p[ballk_[3 * b]], p[ballk_[3 * b + 1]], p[ballk_[3 * b + 2]]);
      const Eigen::Matrix3d R = pinocchio::exp3(r);
      const Eigen::Quaterniond quat(R);
      for (int i = 0; i < 4; ++i)
        q[ballq_[b] + i] = quat.coeffs()[i];            // x, y, z, w
      for (int i = 0; i < 3; ++i)
        v[ballv_[b] + i] = w[ballk_[3 * b + i]];
    }
    return py::make_tuple(qa, va);
  }

private:
  long nq_, nv_, bq_, bv_, n_in_;
  std::vector<long> hq_, hv_, hs_, ballq_, ballv_, ballk_;
};

void bind_state(py::module_ & mod)
{
  py::class_<StateMap>(mod, "StateMap")
    .def(py::init<long, long, long, long, long, IArr, IArr, IArr, IArr, IArr, IArr>(), py::arg("nq"), py::arg("nv"),
         py::arg("base_q"), py::arg("base_v"), py::arg("n_in"), py::arg("hq"), py::arg("hv"), py::arg("hs"),
         py::arg("ball_q"), py::arg("ball_v"), py::arg("ball_k"))
    .def("convert", &StateMap::convert, py::arg("position"), py::arg("velocity"), py::arg("base_position"),
         py::arg("base_quat_xyzw"), py::arg("lin_vel_local"), py::arg("ang_vel_local"));
}
