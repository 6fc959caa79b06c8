// The per-tick buffers of the compiled tick (tick.cpp writes them, task.cpp reads them): plain
// Eigen, no Pinocchio, so that the task rows compile without the Pinocchio headers.
#pragma once

#include <Eigen/Core>

namespace tsc_native
{
  using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  using Vec = Eigen::VectorXd;
  using RowMat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

  /// The terms of one tick (names as in dynamics.Dynamics) and the last constrained dynamics.
  struct TickTerms
  {
    long nq = 0, nv = 0, nu = 0, n = 0;   // coordinates, velocities, motors, points
    double mass = 0.0;
    Vec q, v;
    RowMat Minv, BH, Ag, P, pdot, omega, pt_rows, rows;   // pt_rows: [J_p, drift] per point row
    Vec tau_p, dAg_v, hg, com;
    RowMat3 R_base;
    RowMat X, Y;   // ConstrainedDynamics: [Abar, bbar] and -[A, b] of the last elimination
  };
} // namespace tsc_native
