// flip_transport._rcl_io's wait sets: Waiter, the simulator's CommandWait and the controller's StateWait.
// (one translation unit: only rcl_io.cpp includes it, so its names stay in an anonymous namespace)
#pragma once

#include "command_cdr.h"
#include "rcl_common.h"

namespace {

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
