// flip_transport._rcl_io: the lockstep's per-step messages (sim_node's and tsc_node's) on rcl's C API (the rcl of the
// rclpy wheel), without the Python around rclpy's publish, wait set and take.
//
// The publishers, subscriptions, guard condition and context are rclpy's (their `pointer`s): rclpy
// creates and destroys them; this module only uses them in between (``CommandWait.close()`` before
// the subscriptions are destroyed).  Messages stay serialized (CDR) as in flip_transport.lockstep.
//
// SimLoop is sim_node's compiled stepping loop (lockstep with a controller): the routine steps back
// to back (publish the state, wait for its command, step MuJoCo through the C table of
// stepper_api.h), back to Python at anything else (sim_node.SimNode._compiled_steps).
#include "stepper_api.h"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <rcl/error_handling.h>
#include <rcl/publisher.h>
#include <rcl/subscription.h>
#include <rcl/wait.h>
#include <rmw/serialized_message.h>

#include <chrono>
#include <cstdint>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace py = pybind11;

namespace {

template <typename T>
T *from_address(std::uintptr_t p) {
  if (p == 0) throw std::invalid_argument("null rcl handle");
  return reinterpret_cast<T *>(p);
}

[[noreturn]] void rcl_fail(const char *what) {
  std::string e = rcl_get_error_string().str;
  rcl_reset_error();
  throw std::runtime_error(std::string(what) + ": " + e);
}

// Publish n serialized bytes (no copy); with stamp_ns >= 0 its header stamp (the CDR bytes 4..12:
// int32 sec, uint32 nanosec) is written first.  No Python: callable without the GIL.
void publish_raw(rcl_publisher_t *publisher, std::uint8_t *data, std::size_t n, std::int64_t stamp_ns) {
  if (stamp_ns >= 0) {
    if (n < 12) throw std::invalid_argument("message too short for a header stamp");
    const std::int32_t sec = static_cast<std::int32_t>(stamp_ns / 1000000000);
    const std::uint32_t nsec = static_cast<std::uint32_t>(stamp_ns % 1000000000);
    std::memcpy(data + 4, &sec, 4);
    std::memcpy(data + 8, &nsec, 4);
  }
  rcl_serialized_message_t msg = rmw_get_zero_initialized_serialized_message();
  msg.buffer = data;
  msg.buffer_length = n;
  msg.buffer_capacity = n;
  msg.allocator = rcutils_get_default_allocator();
  if (rcl_publish_serialized_message(publisher, &msg, nullptr) != RCL_RET_OK)
    rcl_fail("rcl_publish_serialized_message");
}

// Publish a serialized message from a buffer (publish_raw).
void publish(std::uintptr_t publisher, py::buffer buf, std::int64_t stamp_ns) {
  py::buffer_info info = buf.request(stamp_ns >= 0);
  publish_raw(from_address<rcl_publisher_t>(publisher), static_cast<std::uint8_t *>(info.ptr),
              static_cast<std::size_t>(info.size * info.itemsize), stamp_ns);
}

// Take every message queued on a subscription (rclpy's pointer) and return those whose header stamp
// (CDR bytes 4..12) is a multiple of period_ns, as (stamp_ns, bytes), in the order taken: a reader of
// a per-step stream that keeps one message in ten without a Python call for each (state_publisher).
py::list take_on_grid(std::uintptr_t subscription, std::int64_t period_ns) {
  if (period_ns <= 0) throw std::invalid_argument("period_ns must be > 0");
  rcl_subscription_t *sub = from_address<rcl_subscription_t>(subscription);
  rcutils_allocator_t alloc = rcutils_get_default_allocator();
  rcl_serialized_message_t taken = rmw_get_zero_initialized_serialized_message();
  if (rmw_serialized_message_init(&taken, 4096, &alloc) != RMW_RET_OK) {
    rcutils_reset_error();
    throw std::runtime_error("rmw_serialized_message_init failed");
  }
  std::unique_ptr<rcl_serialized_message_t, void (*)(rcl_serialized_message_t *)> guard(
      &taken, [](rcl_serialized_message_t *m) { rmw_serialized_message_fini(m); });
  py::list out;
  for (;;) {
    rmw_message_info_t info = rmw_get_zero_initialized_message_info();
    rcl_ret_t rc = rcl_take_serialized_message(sub, &taken, &info, nullptr);
    if (rc == RCL_RET_SUBSCRIPTION_TAKE_FAILED) break;
    if (rc != RCL_RET_OK) rcl_fail("rcl_take_serialized_message");
    if (taken.buffer_length < 12) continue;
    std::int32_t sec;
    std::uint32_t nsec;
    std::memcpy(&sec, taken.buffer + 4, 4);
    std::memcpy(&nsec, taken.buffer + 8, 4);
    const std::int64_t ns = std::int64_t(sec) * 1000000000 + nsec;
    if (ns % period_ns == 0)
      out.append(py::make_tuple(ns, py::bytes(reinterpret_cast<const char *>(taken.buffer), taken.buffer_length)));
  }
  return out;
}

// Little-endian CDR reader (alignment relative to the end of the 4-byte encapsulation header).
struct Cdr {
  const std::uint8_t *b;
  std::size_t n, pos = 4;
  bool ok = true;
  void align(std::size_t a) { pos = 4 + ((pos - 4 + a - 1) / a) * a; }
  const std::uint8_t *take(std::size_t size, std::size_t a) {
    align(a);
    if (!ok || pos + size > n) {
      ok = false;
      return nullptr;
    }
    const std::uint8_t *p = b + pos;
    pos += size;
    return p;
  }
  std::uint32_t u32() {
    const std::uint8_t *p = take(4, 4);
    std::uint32_t v = 0;
    if (p) std::memcpy(&v, p, 4);
    return v;
  }
  void skip_string() {
    std::uint32_t len = u32();
    if (ok) take(len, 1);
  }
};

// flip_msgs/MotorCommand: header (stamp, frame_id), uint64 step, string[] name, float64[] effort, ...
// Returns false for a malformed message; else step and the effort sequence (count, first byte).
bool read_command(const std::uint8_t *b, std::size_t n, std::uint64_t &step, std::uint32_t &count,
                  const std::uint8_t *&effort) {
  Cdr c{b, n};
  if (n < 4 || b[1] != 0x01) return false;  // CDR_LE (0x0001) only
  c.take(8, 4);                              // stamp
  c.skip_string();                           // frame_id
  const std::uint8_t *s = c.take(8, 8);
  if (s) std::memcpy(&step, s, 8);
  std::uint32_t names = c.u32();
  for (std::uint32_t i = 0; c.ok && i < names; ++i) c.skip_string();
  count = c.u32();
  if (!c.ok || count > (n - c.pos) / 8 + 1) return false;
  effort = count ? c.take(8 * std::size_t(count), 8) : b + c.pos;
  return c.ok;
}

// An rcl wait set of its own (subscriptions and one guard condition) and a buffer that serialized
// messages are taken into; close() (or the destructor) releases both.
class Waiter {
 public:
  void close() {
    if (!open_) return;
    open_ = false;
    rcl_wait_set_fini(&ws_);
    rmw_serialized_message_fini(&taken_);
  }

 protected:
  Waiter(std::uintptr_t context, std::size_t subscriptions, std::size_t capacity) {
    ws_ = rcl_get_zero_initialized_wait_set();
    if (rcl_wait_set_init(&ws_, subscriptions, 1, 0, 0, 0, 0, from_address<rcl_context_t>(context),
                          rcl_get_default_allocator()) != RCL_RET_OK)
      rcl_fail("rcl_wait_set_init");
    taken_ = rmw_get_zero_initialized_serialized_message();
    auto alloc = rcutils_get_default_allocator();
    if (rmw_serialized_message_init(&taken_, capacity, &alloc) != RMW_RET_OK) {
      rcl_wait_set_fini(&ws_);
      throw std::runtime_error("rmw_serialized_message_init failed");
    }
    open_ = true;
  }
  ~Waiter() { close(); }

 public:
  void check_open() const {
    if (!open_) throw std::runtime_error("closed");
  }

 protected:
  // rcl_wait, with the GIL released unless the caller has (has_gil false): RCL_RET_OK, or RCL_RET_TIMEOUT
  rcl_ret_t wait_for(std::int64_t timeout_ns, bool has_gil = true) {
    rcl_ret_t rc;
    if (has_gil) {
      py::gil_scoped_release nogil;
      rc = rcl_wait(&ws_, timeout_ns);
    } else {
      rc = rcl_wait(&ws_, timeout_ns);
    }
    if (rc != RCL_RET_OK && rc != RCL_RET_TIMEOUT) rcl_fail("rcl_wait");
    return rc;
  }

  rcl_wait_set_t ws_;
  rcl_serialized_message_t taken_;
  bool open_ = false;
};

// Waits for the /motor_command of one step on its own rcl wait set (command and reference
// subscriptions, the SIGINT guard condition).
class CommandWait : public Waiter {
 public:
  enum Status { GOT = 0, TIMEOUT = 1, REFERENCE = 2, INTERRUPTED = 3, WRONG_SIZE = 4 };

  CommandWait(std::uintptr_t context, std::uintptr_t command_sub, std::uintptr_t reference_sub,
              std::uintptr_t sigint_guard)
      : Waiter(context, 2, 1024),
        cmd_(from_address<rcl_subscription_t>(command_sub)),
        ref_(from_address<rcl_subscription_t>(reference_sub)),
        guard_(from_address<rcl_guard_condition_t>(sigint_guard)) {}

  // Wait up to timeout_ns for the command answering `step`; its torques go to u (of size u.size()).
  int wait(std::uint64_t step, std::int64_t timeout_ns, py::array_t<double, py::array::c_style> u) {
    check_open();
    auto out = u.mutable_unchecked<1>();
    return wait_raw(step, timeout_ns, out.mutable_data(0), static_cast<std::size_t>(out.shape(0)), true);
  }

  // wait on a raw buffer of nu torques; has_gil false: called with the GIL released (no Python)
  int wait_raw(std::uint64_t step, std::int64_t timeout_ns, double *u, std::size_t nu, bool has_gil) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_ns);
    for (;;) {
      // commands already queued first (the last wait may have left some)
      int got = take_commands(step, u, nu);
      if (got >= 0) return got;
      const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(
          deadline - std::chrono::steady_clock::now()).count();
      if (left <= 0) return TIMEOUT;
      if (rcl_wait_set_clear(&ws_) != RCL_RET_OK) rcl_fail("rcl_wait_set_clear");
      if (rcl_wait_set_add_subscription(&ws_, cmd_, nullptr) != RCL_RET_OK ||
          rcl_wait_set_add_subscription(&ws_, ref_, nullptr) != RCL_RET_OK ||
          rcl_wait_set_add_guard_condition(&ws_, guard_, nullptr) != RCL_RET_OK)
        rcl_fail("rcl_wait_set_add");
      if (wait_for(left, has_gil) == RCL_RET_TIMEOUT) return TIMEOUT;
      if (ws_.guard_conditions[0]) return INTERRUPTED;
      if (ws_.subscriptions[1]) return REFERENCE;
    }
  }

  std::uint32_t last_count() const { return last_count_; }
  std::uint64_t malformed() const { return malformed_; }

 private:
  // Take every queued command: GOT / WRONG_SIZE for the one answering `step`, -1 if none did.
  int take_commands(std::uint64_t step, double *u, std::size_t nu) {
    for (;;) {
      rmw_message_info_t info = rmw_get_zero_initialized_message_info();
      rcl_ret_t rc = rcl_take_serialized_message(cmd_, &taken_, &info, nullptr);
      if (rc == RCL_RET_SUBSCRIPTION_TAKE_FAILED) return -1;
      if (rc != RCL_RET_OK) rcl_fail("rcl_take_serialized_message");
      std::uint64_t k = 0;
      std::uint32_t count = 0;
      const std::uint8_t *effort = nullptr;
      if (!read_command(taken_.buffer, taken_.buffer_length, k, count, effort)) {
        ++malformed_;
        continue;
      }
      if (k != step) continue;  // an answer to an earlier state (re-sent): dropped
      last_count_ = count;
      if (count != nu) return WRONG_SIZE;
      std::memcpy(u, effort, 8 * nu);
      return GOT;
    }
  }

  rcl_subscription_t *cmd_, *ref_;
  rcl_guard_condition_t *guard_;
  std::uint32_t last_count_ = 0;
  std::uint64_t malformed_ = 0;
};

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

// The controller's side: waits until the newest /joint_states and /odom carry the same stamp (a
// state), or a message is queued on one of the other subscriptions (events, references: taken with
// rclpy), or SIGINT.  The two state messages are copied into buffers of this object, which Python
// reads through ``js`` / ``odom`` (memoryviews of the last message of each).
class StateWait : public Waiter {
 public:
  enum { STATE = 1, OTHER = 2, INTERRUPTED = 4, TIMEOUT = 8 };

  StateWait(std::uintptr_t context, std::uintptr_t sigint_guard, std::uintptr_t js_sub, std::uintptr_t odom_sub,
            const std::vector<std::uintptr_t> &others)
      : Waiter(context, 2 + others.size(), 4096),
        js_(from_address<rcl_subscription_t>(js_sub)),
        odom_(from_address<rcl_subscription_t>(odom_sub)),
        guard_(from_address<rcl_guard_condition_t>(sigint_guard)) {
    for (auto p : others) others_.push_back(from_address<rcl_subscription_t>(p));
  }

  // Bitmask of STATE (a new /joint_states whose stamp the newest /odom carries), OTHER (a message
  // queued on another subscription), INTERRUPTED, TIMEOUT.
  int wait(std::int64_t timeout_ns) {
    check_open();
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_ns);
    for (;;) {
      if (take_newest(js_, js_buf_)) js_fresh_ = true;
      take_newest(odom_, odom_buf_);
      int result = others_pending_ ? OTHER : 0;
      const bool odom_behind = !js_buf_.empty() && (odom_buf_.empty() || stamp(odom_buf_) < stamp(js_buf_));
      if (js_fresh_ && !odom_behind && stamp(odom_buf_) == stamp(js_buf_)) {
        js_fresh_ = false;
        result |= STATE;
      }
      if (result) {
        others_pending_ = false;
        return result;
      }
      const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(
          deadline - std::chrono::steady_clock::now()).count();
      if (left <= 0) return TIMEOUT;
      if (rcl_wait_set_clear(&ws_) != RCL_RET_OK) rcl_fail("rcl_wait_set_clear");
      // /odom comes before /joint_states: wake on /joint_states alone unless /odom is behind it
      bool ok = rcl_wait_set_add_subscription(&ws_, js_, nullptr) == RCL_RET_OK;
      if (odom_behind) ok = ok && rcl_wait_set_add_subscription(&ws_, odom_, nullptr) == RCL_RET_OK;
      for (auto *s : others_) ok = ok && rcl_wait_set_add_subscription(&ws_, s, nullptr) == RCL_RET_OK;
      ok = ok && rcl_wait_set_add_guard_condition(&ws_, guard_, nullptr) == RCL_RET_OK;
      if (!ok) rcl_fail("rcl_wait_set_add");
      if (wait_for(left) == RCL_RET_TIMEOUT) return TIMEOUT;
      if (ws_.guard_conditions[0]) return INTERRUPTED;
      for (std::size_t i = 0; i < ws_.size_of_subscriptions; ++i)
        if (ws_.subscriptions[i] && ws_.subscriptions[i] != js_ && ws_.subscriptions[i] != odom_)
          others_pending_ = true;
    }
  }

  py::memoryview js() const { return view(js_buf_); }
  py::memoryview odom() const { return view(odom_buf_); }

 private:
  static std::int64_t stamp(const std::string &b) {
    if (b.size() < 12) return -1;
    std::int32_t sec;
    std::uint32_t nsec;
    std::memcpy(&sec, b.data() + 4, 4);
    std::memcpy(&nsec, b.data() + 8, 4);
    return std::int64_t(sec) * 1000000000 + nsec;
  }
  static py::memoryview view(const std::string &b) {
    return py::memoryview::from_memory(const_cast<char *>(b.data()), static_cast<py::ssize_t>(b.size()), true);
  }
  // Take every queued message of sub; the newest goes to buf. Whether there was one.
  bool take_newest(rcl_subscription_t *sub, std::string &buf) {
    bool any = false;
    for (;;) {
      rmw_message_info_t info = rmw_get_zero_initialized_message_info();
      rcl_ret_t rc = rcl_take_serialized_message(sub, &taken_, &info, nullptr);
      if (rc == RCL_RET_SUBSCRIPTION_TAKE_FAILED) return any;
      if (rc != RCL_RET_OK) rcl_fail("rcl_take_serialized_message");
      buf.assign(reinterpret_cast<const char *>(taken_.buffer), taken_.buffer_length);
      any = true;
    }
  }

  rcl_subscription_t *js_, *odom_;
  std::vector<rcl_subscription_t *> others_;
  rcl_guard_condition_t *guard_;
  std::string js_buf_, odom_buf_;
  bool js_fresh_ = false, others_pending_ = false;
};

}  // namespace

PYBIND11_MODULE(_rcl_io, mod) {
  mod.doc() = "sim_node's per-step messages on rcl's C API (see native/rcl_io.cpp)";
  mod.def("publish", &publish, py::arg("publisher"), py::arg("buf"), py::arg("stamp_ns") = -1,
          "Publish the serialized message in buf (rclpy publisher's pointer); stamp_ns >= 0 writes its "
          "header stamp first.");
  mod.def("take_on_grid", &take_on_grid, py::arg("subscription"), py::arg("period_ns"),
          "Take every queued message of a subscription (rclpy's pointer); return [(stamp_ns, bytes)] of those "
          "whose header stamp is a multiple of period_ns.");
  py::class_<CommandWait> cw(mod, "CommandWait");
  cw.def(py::init<std::uintptr_t, std::uintptr_t, std::uintptr_t, std::uintptr_t>(), py::arg("context"),
         py::arg("command_subscription"), py::arg("reference_subscription"), py::arg("sigint_guard"))
      .def("wait", &CommandWait::wait, py::arg("step"), py::arg("timeout_ns"), py::arg("u"))
      .def("close", &CommandWait::close)
      .def_property_readonly("last_count", &CommandWait::last_count)
      .def_property_readonly("malformed", &CommandWait::malformed);
  cw.attr("GOT") = int(CommandWait::GOT);
  cw.attr("TIMEOUT") = int(CommandWait::TIMEOUT);
  cw.attr("REFERENCE") = int(CommandWait::REFERENCE);
  cw.attr("INTERRUPTED") = int(CommandWait::INTERRUPTED);
  cw.attr("WRONG_SIZE") = int(CommandWait::WRONG_SIZE);

  py::class_<SimLoop> sl(mod, "SimLoop");
  sl.def(py::init<CommandWait &, py::object, std::uintptr_t, std::uintptr_t, std::uintptr_t, py::buffer, py::buffer,
                  py::buffer, py::array, py::array, py::array, py::array, py::array, py::array, py::array, py::array,
                  std::int64_t, std::int64_t, std::int64_t, std::int64_t>(),
         py::keep_alive<1, 2>(), py::arg("command_wait"), py::arg("stepper_api"), py::arg("odom_publisher"),
         py::arg("joint_states_publisher"), py::arg("clock_publisher"), py::arg("odom"), py::arg("joint_states"),
         py::arg("clock"), py::arg("position"), py::arg("velocity"), py::arg("effort"), py::arg("pose"),
         py::arg("twist"), py::arg("command"), py::arg("u_in"), py::arg("u_applied"), py::arg("dt_ns"),
         py::arg("clock_every"), py::arg("resend_ns"), py::arg("spin_every"))
      .def("run", &SimLoop::run, py::arg("k"), py::arg("k_end"))
      .def("set_wrenches", &SimLoop::set_wrenches, py::arg("left_publisher"), py::arg("right_publisher"),
           py::arg("left"), py::arg("right"), py::arg("left_wrench"), py::arg("right_wrench"), py::arg("every"))
      .def_property("detector", &SimLoop::detector, &SimLoop::set_detector)
      .def_property_readonly("event", &SimLoop::event)
      .def_property_readonly("forces", &SimLoop::forces)
      .def_property_readonly("spent", &SimLoop::spent)
      .def_readwrite("clock_k", &SimLoop::clock_k)
      .def_readwrite("sim_step", &SimLoop::sim_step)
      .def_readwrite("body_contact", &SimLoop::body_contact)
      .def_readwrite("clip", &SimLoop::clip)
      .def_readonly("steps", &SimLoop::steps_)
      .def_readonly("last_state_k", &SimLoop::last_state_k_)
      .def_readonly("wait_status", &SimLoop::wait_status_)
      .def_readonly("wait_t0", &SimLoop::wait_t0_);
  sl.attr("END") = int(SimLoop::END);
  sl.attr("SPIN") = int(SimLoop::SPIN);
  sl.attr("PRE_STEP") = int(SimLoop::PRE_STEP);
  sl.attr("WAIT") = int(SimLoop::WAIT);

  py::class_<StateWait> sw(mod, "StateWait");
  sw.def(py::init<std::uintptr_t, std::uintptr_t, std::uintptr_t, std::uintptr_t, const std::vector<std::uintptr_t> &>(),
         py::arg("context"), py::arg("sigint_guard"), py::arg("joint_states_subscription"),
         py::arg("odom_subscription"), py::arg("other_subscriptions"))
      .def("wait", &StateWait::wait, py::arg("timeout_ns"))
      .def("close", &StateWait::close)
      .def_property_readonly("js", &StateWait::js, "the newest /joint_states (serialized; valid until the next wait)")
      .def_property_readonly("odom", &StateWait::odom, "the newest /odom (serialized; valid until the next wait)");
  sw.attr("STATE") = int(StateWait::STATE);
  sw.attr("OTHER") = int(StateWait::OTHER);
  sw.attr("INTERRUPTED") = int(StateWait::INTERRUPTED);
  sw.attr("TIMEOUT") = int(StateWait::TIMEOUT);
}
