// Compiled state conversion (tsc_controller._native.StateMap): what state.StateConverter.from_ros
// computes in numpy and Pinocchio's Python bindings, in one call: hinge positions and velocities
// copied into (q, v), each ball joint's rotation vector r turned into its quaternion by
// pinocchio::exp3 and Eigen's quaternion from a rotation matrix (the functions pin.exp3 and
// pin.Quaternion call), the floating base's pose and twist set.  The base quaternion comes
// normalised to ``convert``: numpy's norm is BLAS's dot.  ``convert_cdr`` reads the same arrays
// straight from the serialized /joint_states and /odom (a layout set once, checked per message) and
// normalises the quaternion itself, as OpenBLAS's dot of four doubles rounds: x0*x0, then a fused
// multiply-add per element (the controller node's per-step path; tests/unit/test_tsc_domains.py).
#include <pinocchio/fwd.hpp>

#include <pinocchio/spatial.hpp>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>
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
    return fill(p, w, bp, bqt, l, a);
  }

  /// The layout of the serialized messages ``convert_cdr`` reads: per message its size, the byte runs
  /// outside its numeric fields and stamp as (offset, bytes) (frame ids, joint names, sequence
  /// lengths: what flip_transport.cdr.MessageReader compares), and the offsets of position and velocity (n_in
  /// doubles each; /joint_states), pose (7) and twist (6; /odom).
  void set_cdr_layout(py::ssize_t js_size, const py::list & js_runs, py::ssize_t position_offset,
                      py::ssize_t velocity_offset, py::ssize_t odom_size, const py::list & odom_runs,
                      py::ssize_t pose_offset, py::ssize_t twist_offset)
  {
    const py::ssize_t n8 = 8 * n_in_;
    if (position_offset < 0 || position_offset + n8 > js_size || velocity_offset < 0
        || velocity_offset + n8 > js_size || pose_offset < 0 || pose_offset + 56 > odom_size
        || twist_offset < 0 || twist_offset + 48 > odom_size)
      throw std::invalid_argument("StateMap.set_cdr_layout: a field outside its message");
    js_ = Layout{js_size, runs(js_runs, js_size)};
    odom_ = Layout{odom_size, runs(odom_runs, odom_size)};
    pos_off_ = position_offset;
    vel_off_ = velocity_offset;
    pose_off_ = pose_offset;
    twist_off_ = twist_offset;
    has_layout_ = true;
  }

  /// (q, v) from a serialized /joint_states and /odom of the layout set, or None when there is no
  /// layout or a message has another one (other names, frame ids, lengths).
  py::object convert_cdr(const py::buffer & js, const py::buffer & odom) const
  {
    if (!has_layout_)
      return py::none();
    const py::buffer_info jb = js.request(), ob = odom.request();
    const auto * jp = static_cast<const unsigned char *>(jb.ptr);
    const auto * op = static_cast<const unsigned char *>(ob.ptr);
    if (jb.itemsize != 1 || ob.itemsize != 1 || !js_.matches(jp, jb.size) || !odom_.matches(op, ob.size))
      return py::none();
    pbuf_.resize(n_in_);
    wbuf_.resize(n_in_);
    std::memcpy(pbuf_.data(), jp + pos_off_, 8 * n_in_);       // CDR doubles need not be 8-aligned here
    std::memcpy(wbuf_.data(), jp + vel_off_, 8 * n_in_);
    double pose[7], twist[6];
    std::memcpy(pose, op + pose_off_, sizeof pose);
    std::memcpy(twist, op + twist_off_, sizeof twist);
    const double * x = pose + 3;
    const double n = std::sqrt(std::fma(x[3], x[3], std::fma(x[2], x[2], std::fma(x[1], x[1], x[0] * x[0]))));
    double quat[4];
    for (int i = 0; i < 4; ++i)
      quat[i] = x[i] / n;
    return fill(pbuf_.data(), wbuf_.data(), pose, quat, twist, twist + 3);
  }

private:
  struct Layout
  {
    py::ssize_t size = -1;
    std::vector<std::pair<py::ssize_t, std::string>> runs;

    bool matches(const unsigned char * p, py::ssize_t n) const
    {
      if (n != size)
        return false;
      for (const auto & r : runs)
        if (std::memcmp(p + r.first, r.second.data(), r.second.size()) != 0)
          return false;
      return true;
    }
  };

  static std::vector<std::pair<py::ssize_t, std::string>> runs(const py::list & in, py::ssize_t size)
  {
    std::vector<std::pair<py::ssize_t, std::string>> out;
    for (const auto & item : in)
    {
      const auto t = item.cast<py::tuple>();
      const auto off = t[0].cast<py::ssize_t>();
      auto bytes = t[1].cast<std::string>();
      if (off < 0 || off + py::ssize_t(bytes.size()) > size)
        throw std::invalid_argument("StateMap.set_cdr_layout: a byte run outside its message");
      out.emplace_back(off, std::move(bytes));
    }
    return out;
  }

  py::tuple fill(const double * p, const double * w, const double * bp, const double * bqt, const double * l,
                 const double * a) const
  {
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

  long nq_, nv_, bq_, bv_, n_in_;
  std::vector<long> hq_, hv_, hs_, ballq_, ballv_, ballk_;
  bool has_layout_ = false;
  Layout js_, odom_;
  py::ssize_t pos_off_ = 0, vel_off_ = 0, pose_off_ = 0, twist_off_ = 0;
  mutable std::vector<double> pbuf_, wbuf_;
};

void bind_state(py::module_ & mod)
{
  py::class_<StateMap>(mod, "StateMap")
    .def(py::init<long, long, long, long, long, IArr, IArr, IArr, IArr, IArr, IArr>(), py::arg("nq"), py::arg("nv"),
         py::arg("base_q"), py::arg("base_v"), py::arg("n_in"), py::arg("hq"), py::arg("hv"), py::arg("hs"),
         py::arg("ball_q"), py::arg("ball_v"), py::arg("ball_k"))
    .def("convert", &StateMap::convert, py::arg("position"), py::arg("velocity"), py::arg("base_position"),
         py::arg("base_quat_xyzw"), py::arg("lin_vel_local"), py::arg("ang_vel_local"))
    .def("set_cdr_layout", &StateMap::set_cdr_layout, py::arg("js_size"), py::arg("js_runs"),
         py::arg("position_offset"), py::arg("velocity_offset"), py::arg("odom_size"), py::arg("odom_runs"),
         py::arg("pose_offset"), py::arg("twist_offset"))
    .def("convert_cdr", &StateMap::convert_cdr, py::arg("js"), py::arg("odom"));
}
