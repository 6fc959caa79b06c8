// The motor torque-speed envelope in C++, one definition for the simulator's torque clip
// (cassie_flip_sim native/step.cpp) and the controller's QP bounds (tsc_controller native/limits.cpp).
// Cassie's published curve, as its simulators apply it (cassie-mujoco-sim cassiemujoco.c motor()):
//   tlim = min(tmax, 2 tmax (1 - |w| / wmax)), clamped at 0, for either sign of the torque.
// cassie_model.motor_limits.available_fraction is the Python form; they are tested equal bit for bit,
// NaN speeds included (NaN in, NaN out, as numpy's minimum/maximum).
#pragma once

#include <cmath>

namespace cassie_model
{
  /// Share of a motor's torque limit available at joint speed w, 1/w0 = inv_w0 (0: no speed limit).
  inline double available_fraction(double w, double inv_w0)
  {
    const double r = 2.0 * (1.0 - std::fabs(w) * inv_w0);
    if (r != r) return r;
    return r < 0.0 ? 0.0 : (r > 1.0 ? 1.0 : r);
  }
} // namespace cassie_model
