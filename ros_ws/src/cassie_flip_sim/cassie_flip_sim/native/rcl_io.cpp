// cassie_flip_sim._rcl_io: the lockstep's per-step messages (sim_node's and tsc_node's) on rcl's C API (the rcl of the
// rclpy wheel), without the Python around rclpy's publish, wait set and take.
//
// The publishers, subscriptions, guard condition and context are rclpy's (their `pointer`s): rclpy
// creates and destroys them; this module only uses them in between (``CommandWait.close()`` before
// the subscriptions are destroyed).  Messages stay serialized (CDR) as in cassie_flip_sim.lockstep.
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

// Publish a serialized message from a buffer (no copy); with stamp_ns >= 0 its header stamp (the CDR
// bytes 4..12: int32 sec, uint32 nanosec) is written first.
void publish(std::uintptr_t publisher, py::buffer buf, std::int64_t stamp_ns) {
  py::buffer_info info = buf.request(stamp_ns >= 0);
  auto *data = static_cast<std::uint8_t *>(info.ptr);
  const std::size_t n = static_cast<std::size_t>(info.size * info.itemsize);
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
  if (rcl_publish_serialized_message(from_address<rcl_publisher_t>(publisher), &msg, nullptr) != RCL_RET_OK)
    rcl_fail("rcl_publish_serialized_message");
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
  void check_open() const {
    if (!open_) throw std::runtime_error("closed");
  }
  // rcl_wait with the GIL released: RCL_RET_OK, or RCL_RET_TIMEOUT
  rcl_ret_t wait_for(std::int64_t timeout_ns) {
    rcl_ret_t rc;
    {
      py::gil_scoped_release nogil;
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
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_ns);
    for (;;) {
      // commands already queued first (the last wait may have left some)
      int got = take_commands(step, out.mutable_data(0), static_cast<std::size_t>(out.shape(0)));
      if (got >= 0) return got;
      const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(
          deadline - std::chrono::steady_clock::now()).count();
      if (left <= 0) return TIMEOUT;
      if (rcl_wait_set_clear(&ws_) != RCL_RET_OK) rcl_fail("rcl_wait_set_clear");
      if (rcl_wait_set_add_subscription(&ws_, cmd_, nullptr) != RCL_RET_OK ||
          rcl_wait_set_add_subscription(&ws_, ref_, nullptr) != RCL_RET_OK ||
          rcl_wait_set_add_guard_condition(&ws_, guard_, nullptr) != RCL_RET_OK)
        rcl_fail("rcl_wait_set_add");
      if (wait_for(left) == RCL_RET_TIMEOUT) return TIMEOUT;
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

PYBIND11_MODULE(_rcl_io, mod) {
  mod.doc() = "sim_node's per-step messages on rcl's C API (see native/rcl_io.cpp)";
  mod.def("publish", &publish, py::arg("publisher"), py::arg("buf"), py::arg("stamp_ns") = -1,
          "Publish the serialized message in buf (rclpy publisher's pointer); stamp_ns >= 0 writes its "
          "header stamp first.");
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
