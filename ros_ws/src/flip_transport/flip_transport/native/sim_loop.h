// flip_transport._rcl_io: SimLoop, sim_node's compiled stepping loop.
// (one translation unit: only rcl_io.cpp includes it, so its names stay in an anonymous namespace)
#pragma once

#include "rcl_common.h"
#include "waits.h"

namespace {

// sim_node's compiled stepping loop: lockstep steps k, k+1, ... as SimNode.run's loop takes them
// (its module doc), each one: publish the state (/clock when due, /odom, /joint_states, from the
// serialized templates), wait for the command of step k (CommandWait::wait), step MuJoCo with it
// (the Stepper's C table), run the contact detector (cassie_flip_sim.contacts.ContactDetector's
// copy), and every wrench_every-th step publish the feet's wrenches of state k stamped k dt (set_wrenches).  run()
// returns to Python (with the GIL released in between, no Python runs) whenever anything is not
// routine:
//   PRE_STEP  before a step whose pre-step checks are not empty (a contact event of the last step
//             to publish, the body contact changed): Python does them, then calls run() again;
//   WAIT      the wait for step k's command reported anything but GOT (its state is sent; Python
//             goes on waiting: re-send, reference, wrong size, interrupted);
//   END       k reached k_end;
//   SPIN      k reached a multiple of spin_every (the loop's executor spin, signal handlers);
// The first step of a call has had its pre-step checks in Python.  The wall time of the parts is
// summed per call as SimNode.run's `spent` does (steady_clock = time.perf_counter's clock).
class SimLoop {
 public:
  enum Reason { END = 0, SPIN = 1, PRE_STEP = 2, WAIT = 3 };

  SimLoop(CommandWait &wait, py::object stepper_api, std::uintptr_t odom_pub, std::uintptr_t js_pub,
          std::uintptr_t clock_pub, py::buffer odom_buf, py::buffer js_buf, py::buffer clock_buf, py::array pos,
          py::array vel, py::array eff, py::array pose, py::array twist, py::array command, py::array u_in,
          py::array u_applied, std::int64_t dt_ns, std::int64_t clock_every, std::int64_t resend_ns,
          std::int64_t spin_every)
      : wait_(wait), refs_(py::make_tuple(stepper_api, odom_buf, js_buf, clock_buf, pos, vel, eff, pose, twist,
                                          command, u_in, u_applied)),
        odom_pub_(from_address<rcl_publisher_t>(odom_pub)), js_pub_(from_address<rcl_publisher_t>(js_pub)),
        clock_pub_(from_address<rcl_publisher_t>(clock_pub)), dt_ns_(dt_ns), clock_every_(clock_every),
        resend_ns_(resend_ns), spin_every_(spin_every) {
    if (!PyCapsule_IsValid(stepper_api.ptr(), CFS_STEPPER_API_CAPSULE))
      throw std::invalid_argument("SimLoop: stepper_api is no " CFS_STEPPER_API_CAPSULE " capsule");
    api_ = static_cast<CfsStepperApi *>(PyCapsule_GetPointer(stepper_api.ptr(), CFS_STEPPER_API_CAPSULE));
    if (api_->version != CFS_STEPPER_API_VERSION) throw std::invalid_argument("SimLoop: stepper API version");
    if (dt_ns <= 0 || clock_every <= 0 || resend_ns <= 0) throw std::invalid_argument("SimLoop: dt_ns, clock_every, resend_ns > 0");
    for (auto *b : {&odom_buf, &js_buf, &clock_buf}) {
      bufs_.emplace_back(new py::buffer_info(b->request(true)));     // held: the bytes cannot move
      if (bufs_.back()->size * bufs_.back()->itemsize < 12) throw std::invalid_argument("SimLoop: message too short");
    }
    const long nj = api_->n_joints, nu = api_->n_motors;
    pos_ = field(pos, nj, "pos"), vel_ = field(vel, nj, "vel"), eff_ = field(eff, nj, "eff");
    pose_ = field(pose, 7, "pose"), twist_ = field(twist, 6, "twist");
    command_ = reinterpret_cast<double *>(aligned(command, nu, "command"));
    u_in_ = reinterpret_cast<double *>(aligned(u_in, nu, "u_in"));
    u_applied_ = field(u_applied, nu, "u_applied");
    nu_ = static_cast<std::size_t>(nu);
  }

  // Steps from k (pre-step checks done) until a Reason; k_end < 0: no end.  Returns (reason, k):
  // the next step (END, SPIN, PRE_STEP), or the step whose command is awaited (WAIT).
  py::tuple run(std::int64_t k, std::int64_t k_end) {
    wait_.check_open();
    steps_ = 0;
    last_state_k_ = -1;
    wait_status_ = -1;
    has_event_ = false;
    spent_ = Spent{};
    int reason;
    {
      py::gil_scoped_release nogil;
      reason = loop(k, k_end);
    }
    return py::make_tuple(reason, k);
  }

  // The feet's wrench topics: their publishers (rclpy's pointers), serialized WrenchStamped templates
  // and float64 views of their 6 numbers (force, torque), published for every step k with
  // k % every == 0 (every 0: none), as SimNode._publish_wrenches does.
  void set_wrenches(std::uintptr_t left_pub, std::uintptr_t right_pub, py::buffer left_buf, py::buffer right_buf,
                    py::array left, py::array right, std::int64_t every) {
    if (every < 0) throw std::invalid_argument("SimLoop.set_wrenches: every >= 0");
    wrench_pub_[0] = from_address<rcl_publisher_t>(left_pub);
    wrench_pub_[1] = from_address<rcl_publisher_t>(right_pub);
    int i = 0;
    for (auto *b : {&left_buf, &right_buf}) {
      wrench_buf_[i].reset(new py::buffer_info(b->request(true)));
      if (wrench_buf_[i]->size * wrench_buf_[i]->itemsize < 12) throw std::invalid_argument("SimLoop: message too short");
      ++i;
    }
    wrench_field_[0] = field(left, 6, "left wrench");
    wrench_field_[1] = field(right, 6, "right wrench");
    wrench_refs_ = py::make_tuple(left_buf, right_buf, left, right);
    wrench_every_ = every;
  }

  // ContactDetector.state() <-> (in_contact, zero_run, onset_step, onset_time, flight_steps,
  // lift_off_force, touch_down_force, lift_off_steps, min_flight_steps)
  py::tuple detector() const {
    const CfsDetector &d = det_;
    return py::make_tuple(d.in_contact, d.zero_run, d.onset_step, d.onset_time, d.flight_steps, d.lift_off_force,
                          d.touch_down_force, d.lift_off_steps, d.min_flight_steps);
  }
  void set_detector(py::tuple t) {
    if (t.size() != 9) throw std::invalid_argument("SimLoop.detector: 9 values");
    CfsDetector d;
    d.in_contact = t[0].cast<bool>(), d.zero_run = t[1].cast<long>(), d.onset_step = t[2].cast<long>();
    d.onset_time = t[3].cast<double>(), d.flight_steps = t[4].cast<long>();
    d.lift_off_force = t[5].cast<double>(), d.touch_down_force = t[6].cast<double>();
    d.lift_off_steps = t[7].cast<long>(), d.min_flight_steps = t[8].cast<long>();
    det_ = d;
  }
  // the last call's contact event: None or (kind, step, time, detected_step, left_force, right_force)
  py::object event() const {
    if (!has_event_) return py::none();
    const CfsEvent &e = event_;
    return py::make_tuple(e.kind, e.step, e.time, e.detected_step, e.left_force, e.right_force);
  }
  py::tuple forces() const { return py::make_tuple(forces_[0], forces_[1]); }
  // the last call's wall time, s: (simulate, publish state, wait for command)
  py::tuple spent() const { return py::make_tuple(spent_.simulate, spent_.publish, spent_.wait); }

  // set before run(): the node's and the simulator's state the loop carries on
  std::int64_t clock_k = -1;      // step of the newest /clock published (SimNode.clock_k)
  long sim_step = 0;              // Simulator.step_index (the detector's step numbers)
  bool body_contact = false;      // SimNode.body_contact
  bool clip = true;               // Simulator.clip_torques
  // read after run()
  long steps_ = 0;                      // steps taken
  std::int64_t last_state_k_ = -1;      // step of the last state published (-1: none)
  int wait_status_ = -1;                // WAIT: CommandWait's status
  double wait_t0_ = 0.0;                // WAIT: when the wait began (time.monotonic's clock), s

 private:
  struct Spent {
    double simulate = 0.0, publish = 0.0, wait = 0.0;
  };
  using Clock = std::chrono::steady_clock;
  static double secs(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

  int loop(std::int64_t &k, std::int64_t k_end) {
    void *s = api_->self;
    std::uint8_t *od = static_cast<std::uint8_t *>(bufs_[0]->ptr), *js = static_cast<std::uint8_t *>(bufs_[1]->ptr),
                 *ck = static_cast<std::uint8_t *>(bufs_[2]->ptr);
    const std::size_t n_od = bufs_[0]->size * bufs_[0]->itemsize, n_js = bufs_[1]->size * bufs_[1]->itemsize,
                      n_ck = bufs_[2]->size * bufs_[2]->itemsize;
    for (bool first = true;; first = false) {
      // pre-step checks (SimNode.run: contact events to publish, a body contact that changed)
      if (!first && (has_event_ || (api_->body_contact(s) != 0) != body_contact)) return PRE_STEP;
      // SimNode._publish_state
      const auto t0 = Clock::now();
      const std::int64_t ns = k * dt_ns_;
      api_->state(s, pos_, vel_, eff_, pose_, twist_);
      if (k % clock_every_ == 0 && k != clock_k) {
        publish_raw(clock_pub_, ck, n_ck, ns);
        clock_k = k;
      }
      publish_raw(odom_pub_, od, n_od, ns);
      publish_raw(js_pub_, js, n_js, ns);
      last_state_k_ = k;
      const auto t1 = Clock::now();
      spent_.publish += secs(t1 - t0);
      // SimNode._wait_command_rcl's first wait
      const int status = wait_.wait_raw(static_cast<std::uint64_t>(k), resend_ns_, u_in_, nu_, false);
      const auto t2 = Clock::now();
      spent_.wait += secs(t2 - t1);
      if (status != CommandWait::GOT) {
        wait_status_ = status;
        wait_t0_ = secs(t1.time_since_epoch());
        return WAIT;
      }
      std::memcpy(command_, u_in_, 8 * nu_);
      // Simulator.step (with the wrenches of state k when they are due)
      const bool wrench_due = wrench_every_ > 0 && k % wrench_every_ == 0;
      const double t = api_->time(s);
      api_->step(s, command_, u_applied_, clip ? 1 : 0, forces_, wrench_due ? wrench_ : nullptr);
      if (cfs_detector_update(det_, sim_step, t, forces_[0], forces_[1], &event_)) has_event_ = true;
      ++sim_step;
      ++steps_;
      const auto t3 = Clock::now();
      spent_.simulate += secs(t3 - t2);
      if (wrench_due) {              // SimNode._publish_wrenches
        for (int f = 0; f < 2; ++f) {
          std::memcpy(wrench_field_[f], wrench_ + 6 * f, 6 * sizeof(double));
          publish_raw(wrench_pub_[f], static_cast<std::uint8_t *>(wrench_buf_[f]->ptr),
                      wrench_buf_[f]->size * wrench_buf_[f]->itemsize, ns);
        }
        spent_.publish += secs(Clock::now() - t3);
      }
      ++k;
      if (k_end >= 0 && k >= k_end) return END;
      if (spin_every_ > 0 && k % spin_every_ == 0) return SPIN;
    }
  }

  // a float64 field of n (contiguous, writeable; may be unaligned: views of a serialized message)
  static unsigned char *field(py::array &a, long n, const char *what) {
    if (!a.dtype().is(py::dtype::of<double>()) || a.size() != n || !a.writeable() ||
        !(a.flags() & py::array::c_style))
      throw std::invalid_argument(std::string("SimLoop: ") + what +
                                  ": needs a writeable contiguous float64 array of the right size");
    return static_cast<unsigned char *>(a.mutable_data());
  }
  static unsigned char *aligned(py::array &a, long n, const char *what) {
    unsigned char *p = field(a, n, what);
    if (reinterpret_cast<std::uintptr_t>(p) % alignof(double))
      throw std::invalid_argument(std::string("SimLoop: ") + what + ": needs an aligned array");
    return p;
  }

  CommandWait &wait_;
  py::tuple refs_;     // the Python objects whose memory the loop uses (kept alive)
  std::vector<std::unique_ptr<py::buffer_info>> bufs_;
  const CfsStepperApi *api_ = nullptr;
  rcl_publisher_t *odom_pub_, *js_pub_, *clock_pub_;
  std::int64_t dt_ns_, clock_every_, resend_ns_, spin_every_;
  unsigned char *pos_, *vel_, *eff_, *pose_, *twist_, *u_applied_;
  double *command_, *u_in_;
  std::size_t nu_ = 0;
  CfsDetector det_;
  // the feet's wrenches (set_wrenches): publishers, templates, their number fields, the step's values
  rcl_publisher_t *wrench_pub_[2] = {nullptr, nullptr};
  std::unique_ptr<py::buffer_info> wrench_buf_[2];
  unsigned char *wrench_field_[2] = {nullptr, nullptr};
  py::tuple wrench_refs_;
  std::int64_t wrench_every_ = 0;
  double wrench_[12] = {};
  CfsEvent event_{};
  bool has_event_ = false;
  double forces_[2] = {0.0, 0.0};
  Spent spent_;
};

}  // namespace
