// What the qemu guest's test programs share (can_kernel_system: ctest
// qemu_can_system; can_kernel_force: qemu_can_force): each step and its
// result on stdout with the seconds since the program started, a failure
// that ends the test (caught in main, which prints it and exits 1), and the
// CAN timeouts a software-emulated guest CPU needs.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <string>

#include "massage_cell/can/config.h"

namespace massage_cell::tools::guest {

struct Failure {
  std::string why;
};
[[noreturn]] inline void fail(const std::string& why) { throw Failure{why}; }

inline const auto kStart = std::chrono::steady_clock::now();
/// Seconds since the program started.
inline double since() { return std::chrono::duration<double>(std::chrono::steady_clock::now() - kStart).count(); }

inline void step(const std::string& text) {
  std::printf("[%7.3f] STEP %s\n", since(), text.c_str());
  std::fflush(stdout);
}
inline void ok(const std::string& text) {
  std::printf("[%7.3f]   ok: %s\n", since(), text.c_str());
  std::fflush(stdout);
}

/// Under TCG the guest runs 10-50x slower than the host: SDO >= 300 ms, boot >= 5 s, heartbeat consumer >= 1 s,
/// CiA 402 transitions >= 2 s.
inline void relaxTimeouts(can::CanConfig* config) {
  config->sdo_timeout_ms = std::max<std::uint32_t>(config->sdo_timeout_ms, 300);
  config->boot_timeout_ms = std::max<std::uint32_t>(config->boot_timeout_ms, 5000);
  for (can::AxisConfig& a : config->axes) {
    a.heartbeat_timeout_ms = std::max<std::uint32_t>(a.heartbeatTimeoutMs(), 1000);
    a.enable_timeout_ms = std::max<std::uint32_t>(a.enable_timeout_ms, 2000);
  }
}

}  // namespace massage_cell::tools::guest
