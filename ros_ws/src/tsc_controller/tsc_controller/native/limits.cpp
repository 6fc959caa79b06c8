// Compiled torque-speed envelope of the TSC (tsc_controller._native.torque_bounds, limits.TorqueLimits):
// cassie_model.motor_limits.MotorLimits.bounds, the Python reference, bit for bit (also for
// non-finite speeds), without numpy's per-call overhead.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cmath>
#include <stdexcept>

#include "motor_envelope.h"

namespace py = pybind11;
using DArr = py::array_t<double, py::array::c_style | py::array::forcecast>;

namespace
{

  /// (u_lb, u_ub) = -/+ tau_max * cassie_model::available_fraction(w, 1/w0).
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
      const double a = tm[i] * cassie_model::available_fraction(wp[i], iw[i]);
      l[i] = -a;
      u[i] = a;
    }
    return py::make_tuple(lb, ub);
  }
} // namespace

void bind_limits(py::module_ & mod)
{
  mod.def("torque_bounds", &torque_bounds, py::arg("w"), py::arg("inv_w0"), py::arg("tau_max"),
          "(u_lb, u_ub) of limits.TorqueLimits.bounds");
}
