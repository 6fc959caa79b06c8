// The simulator's step as a plain C table of function pointers, for sim_node's compiled stepping loop
// (flip_transport._rcl_io.SimLoop, native/rcl_io.cpp) to call without Python in between:
// cassie_flip_sim._native (MuJoCo, no ROS; built against this header, installed with flip_transport)
// hands it out in a capsule (Stepper._api()), _rcl_io (rcl, no MuJoCo) calls it.
//
// Also the lift-off / touch-down detector of cassie_flip_sim.contacts.ContactDetector in C++ (CfsDetector), which
// that loop runs after each step as Simulator.step does: the same comparisons in the same order (so
// the same events); its state goes back and forth with the Python detector's between loop calls.
#pragma once

#include <cstdint>

#define CFS_STEPPER_API_CAPSULE "cassie_flip_sim._native.StepperApi"
#define CFS_STEPPER_API_VERSION 2

extern "C" {

struct CfsStepperApi {
  int version;   // CFS_STEPPER_API_VERSION
  void *self;    // the Stepper
  // the MuJoCo time of the state (mjData.time)
  double (*time)(void *self);
  // Stepper.step: u (n motors) clipped when clip, applied; u_out (n float64, maybe unaligned) gets
  // the applied torques, forces the feet's (left, right) normal forces of the step, wrench (nullptr:
  // not computed; else 12 doubles) the feet's wrenches of the state stepped from (foot_wrench.py)
  void (*step)(void *self, const double *u, unsigned char *u_out, int clip, double forces[2], double *wrench);
  // Stepper.state into float64 fields (maybe unaligned) of the sizes Stepper.state checks
  void (*state)(void *self, unsigned char *pos, unsigned char *vel, unsigned char *eff, unsigned char *pose,
                unsigned char *twist);
  // Stepper.body_contact
  int (*body_contact)(void *self);
  long n_motors, n_joints;
};

}  // extern "C"

// contacts.ContactDetector: the state (in_contact, _zero_run, _onset, _flight_steps; onset_step -1
// for an _onset of None) and the thresholds; update() is ContactDetector.update.
struct CfsDetector {
  bool in_contact = true;
  long zero_run = 0;
  long onset_step = -1;
  double onset_time = 0.0;
  long flight_steps = 0;
  double lift_off_force = 1e-9, touch_down_force = 1.0;
  long lift_off_steps = 20, min_flight_steps = 20;
};

// An event of ContactDetector.update: kind 0 LIFT_OFF, 1 TOUCH_DOWN (contacts.Event).
struct CfsEvent {
  int kind;
  long step;
  double time;
  long detected_step;
  double left_force, right_force;
};

// ContactDetector.update: whether an event came (then in *ev).
inline bool cfs_detector_update(CfsDetector &d, long step, double time, double left, double right, CfsEvent *ev)
{
  if (d.in_contact) {
    if (left <= d.lift_off_force && right <= d.lift_off_force) {
      if (d.zero_run == 0) {
        d.onset_step = step;
        d.onset_time = time;
      }
      d.zero_run += 1;
      if (d.zero_run >= d.lift_off_steps) {
        d.in_contact = false;
        d.zero_run = 0;
        d.flight_steps = 0;
        *ev = CfsEvent{0, d.onset_step, d.onset_time, step, left, right};
        return true;
      }
    } else {
      d.zero_run = 0;
    }
    return false;
  }
  d.flight_steps += 1;
  const double most = right > left ? right : left;     // Python's max(left, right)
  if (d.flight_steps > d.min_flight_steps && most > d.touch_down_force) {
    d.in_contact = true;
    *ev = CfsEvent{1, step, time, step, left, right};
    return true;
  }
  return false;
}
