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
//
// The parts: rcl_common.h (handles, errors, publish_raw), command_cdr.h (the command's CDR),
// waits.h (CommandWait, StateWait), sim_loop.h (SimLoop); here publish, take_on_grid and the module.
#include "rcl_common.h"
#include "sim_loop.h"
#include "waits.h"

namespace {

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
