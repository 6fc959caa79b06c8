// Compiled torque-speed envelope of the TSC (tsc_controller._native.torque_bounds): the bounds of
// limits.TorqueLimits.bounds without numpy's per-call overhead.  The reference is the Python
// definition, cassie_flip_sim.motor_limits.available_torque (Cassie's published motor model):
//   tlim = clamp(2 tau_max (1 - |w|/w0), 0, tau_max),  -tlim <= u <= tlim,
// here operation for operation in its order (x = |w| * (1/w0); t = ((1 - x) * 2) * tau_max;
// min(t, tau_max); max(., 0), NaN propagating as numpy's minimum / maximum), so the results are equal
// bit for bit (built with -ffp-contract=off).  The simulator's compiled step has the same copy
// (cassie_flip_sim/native/step.cpp).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cmath>
#include <stdexcept>

namespace py = pybind11;
using DArr = py::array_t<double, py::array::c_style | py::array::forcecast>;

namespace
{
  // np.minimum(a, b) / np.maximum(a, b): a NaN in either gives NaN
  inline double np_min(double a, double b)
  {
    return a != a ? a : (b != b ? b : (a < b ? a : b));
  }
  inline double np_max(double a, double b)
  {
    return a != a ? a : (b != b ? b : (a > b ? a : b));
  }

  /// motor_limits.available_torque: clamp(2 tau_max (1 - |w| inv_w0), 0, tau_max)
  inline double available_torque(double w, double tau_max, double inv_w0)
  {
    const double t = (1.0 - std::fabs(w) * inv_w0) * 2.0 * tau_max;
    return np_max(np_min(t, tau_max), 0.0);
  }

  /// (u_lb, u_ub) = (-tlim, tlim), tlim = available_torque per motor.
  py::tuple torque_bounds(const DArr & w, const DArr & inv_w0, const DArr & tau_max)
  {
    const py::ssize_t n = w.size();
    if (inv_w0.size() != n || tau_max.size() != n)
      throw std::invalid_argument("torque_bounds: sizes differ");
    py::array_t<double> lb(n), ub(n);
    double *l = lb.mutable_data(), *u = ub.mutable_data();
    const double *wp = w.data(), *iw = inv_w0.data(), *tm = tau_max.data();
    for (py::ssize_t i = 0; i < n; ++i)
    {
      const double t = available_torque(wp[i], tm[i], iw[i]);
      l[i] = -t;
      u[i] = t;
    }
    return py::make_tuple(lb, ub);
  }
} // namespace

void bind_limits(py::module_ & mod)
{
  mod.def("torque_bounds", &torque_bounds, py::arg("w"), py::arg("inv_w0"), py::arg("tau_max"),
          "(u_lb, u_ub) of limits.TorqueLimits.bounds");
}
