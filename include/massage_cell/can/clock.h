// Time source of the CAN stack. Everything that times out (SDO, heartbeat,
// CiA 402 transitions, SYNC period, simulated motion) reads a Clock, so tests
// can run the master and the simulated drives on a VirtualClock they advance
// by hand (deterministic, no sleeps), and the tools on the steady clock.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>

namespace massage_cell::can {

using Duration = std::chrono::nanoseconds;
using TimePoint = std::chrono::steady_clock::time_point;

/// A gap between two polls of one's own longer than this is a stall of one's own thread (a paused or overloaded host),
/// not silence on the bus: far beyond the master's and the simulated drives' poll periods (1-2 ms) and a SYNC period
/// (10 ms), well under the heartbeat timeouts (150-300 ms). A heartbeat consumer does not count such a stall against
/// its producer: on a real bus what the producer sent meanwhile waits in the receive queue (drained first), and a
/// simulated producer paused with the host sent nothing.
constexpr Duration kOwnStall = std::chrono::milliseconds(50);

/// The heartbeat consumer's reference after a poll `gap` of one's own: `last` moved on by a stall (gap > kOwnStall),
/// never past `now`; unchanged otherwise.
inline TimePoint pastOwnStall(TimePoint last, Duration gap, TimePoint now) {
  return gap > kOwnStall ? std::min(now, last + gap) : last;
}

/// A monotonic time source.
class Clock {
 public:
  virtual ~Clock() = default;
  virtual TimePoint now() const = 0;
};

/// std::chrono::steady_clock.
class SteadyClock final : public Clock {
 public:
  TimePoint now() const override { return std::chrono::steady_clock::now(); }
  static const SteadyClock& instance() {
    static const SteadyClock clock;
    return clock;
  }
};

/// A clock that only moves when told to (thread-safe); starts at 1 s so that
/// "time 0" never means "never".
class VirtualClock final : public Clock {
 public:
  TimePoint now() const override { return TimePoint(Duration(ns_.load())); }
  void advance(Duration d) { ns_ += d.count(); }
  void set(TimePoint t) { ns_ = t.time_since_epoch().count(); }

 private:
  std::atomic<std::int64_t> ns_{1'000'000'000};
};

/// Milliseconds as a double, for messages.
inline double toMs(Duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

}  // namespace massage_cell::can
