// The output kinds of the compiled task rows (task.cpp: outputs.py's classes), their specs, and the
// angle-rate helper they share; only task.cpp includes it, so its names stay in an anonymous namespace.
#pragma once

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace
{
  enum Kind
  {
    CENTROIDAL,   // CentroidalPitchMomentum: row r of h_g
    FLYWHEEL,     // FlywheelMomentum
    LEG_LENGTH,   // LegLength
    LEG_ANGLE,    // LegAngle
    COM,          // ComPosition
    PELVIS,       // PelvisOrientation
    JOINTS,       // JointPositions
    FOOT_PITCH,   // FootPitch
    FOOT_POINTS,  // FootPoints
    PITCH,        // SagittalPitch (value given per call)
    AXIS,         // PelvisAxisTilt
    JOINT_DIFFERENCES,  // LegAsymmetry
  };

  struct Spec
  {
    Kind kind;
    std::vector<long> i;
    std::vector<double> f;
    long dim, row;   // rows in the stacked task
  };

  // outputs._atan2_rates: angle atan2(u, w) of a planar vector moving at (ud, wd), its gradient
  // (gu, gw), its rate, and the velocity part of its second derivative
  struct Atan2Rates
  {
    double angle, gu, gw, rate, curv;
  };

  Atan2Rates atan2_rates(double u, double w, double ud, double wd)
  {
    const double rho2 = u * u + w * w;
    const double gu = w / rho2, gw = -u / rho2;
    const double s2 = 2.0 * (u * ud + w * wd);
    const double dgu = (wd * rho2 - w * s2) / (rho2 * rho2), dgw = (-ud * rho2 + u * s2) / (rho2 * rho2);
    return {std::atan2(u, w), gu, gw, gu * ud + gw * wd, dgu * ud + dgw * wd};
  }

  Kind kind_of(const std::string & s)
  {
    static const char * names[] = {"centroidal", "flywheel", "leg_length", "leg_angle", "com",
                                   "pelvis", "joints", "foot_pitch", "foot_points", "pitch", "axis",
                                   "joint_differences"};
    for (int k = 0; k < 12; ++k)
      if (s == names[k])
        return Kind(k);
    throw std::invalid_argument("tsc_native: unknown output kind " + s);
  }
} // namespace
