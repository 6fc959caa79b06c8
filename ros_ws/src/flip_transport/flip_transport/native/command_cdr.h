// flip_transport._rcl_io: the MotorCommand read from its serialized (CDR) bytes.
// (one translation unit: only rcl_io.cpp includes it, so its names stay in an anonymous namespace)
#pragma once

#include "rcl_common.h"

namespace {

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

}  // namespace
