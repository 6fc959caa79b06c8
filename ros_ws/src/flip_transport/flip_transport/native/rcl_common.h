// flip_transport._rcl_io's shared helpers: rclpy handles from their pointers, rcl errors as
// exceptions, publishing serialized bytes.
// (one translation unit: only rcl_io.cpp includes it, so its names stay in an anonymous namespace)
#pragma once

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

}  // namespace
