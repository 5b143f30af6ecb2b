// In-process CAN bus (a hub with endpoints) with SocketCAN's local delivery
// semantics, for tests and benches. Every frame sent by one endpoint is
// delivered, in send order, to every OTHER endpoint whose filters accept it
// (CAN_RAW_LOOPBACK, on by default, as on a vcan interface), and to the sender
// itself only when it enabled own-message receive (CAN_RAW_RECV_OWN_MSGS, off
// by default). Turning loopback off on an endpoint means nobody else on the
// hub sees its frames (as on vcan, where loopback is the only delivery).
//
// Fault injection: the whole bus or one endpoint goes bus-off for a duration
// (sends fail, nothing is delivered to/from it, state reports bus-off; it
// recovers by itself like a controller with restart-ms), and frames can be
// dropped (the next N matching ones, or with a seeded probability).
// Thread-safe: one mutex for the hub; receive() waits on a condition variable.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "massage_cell/can/bus.h"

namespace massage_cell::can {

class VirtualBus {
 public:
  struct Hub;  // shared state (defined in virtual_bus.cpp)

  /// One endpoint: a Bus; behaves like one CAN_RAW socket on a vcan interface.
  class Endpoint final : public Bus {
   public:
    Endpoint(std::shared_ptr<Hub> hub, std::string name);
    ~Endpoint() override;
    Endpoint(const Endpoint&) = delete;
    Endpoint& operator=(const Endpoint&) = delete;

    std::string name() const override { return name_; }
    bool send(const can_frame& frame) override;
    std::optional<TimedFrame> receive(Duration timeout) override;
    void setFilters(const std::vector<can_filter>& filters) override;
    BusStatus status() const override;
    /// CAN_RAW_LOOPBACK (default true): other endpoints receive our frames.
    void setLoopback(bool on);
    /// CAN_RAW_RECV_OWN_MSGS (default false): we receive our own frames
    /// (only while loopback is on, as in SocketCAN).
    void setReceiveOwn(bool on);
    /// Frames waiting in the receive queue.
    std::size_t pending() const;

   private:
    friend class VirtualBus;
    std::shared_ptr<Hub> hub_;
    std::string name_;
  };

  /// `clock` stamps received frames and times bus-off periods.
  explicit VirtualBus(const Clock& clock = SteadyClock::instance(), std::size_t queue_limit = 4096);
  ~VirtualBus();
  VirtualBus(const VirtualBus&) = delete;
  VirtualBus& operator=(const VirtualBus&) = delete;

  /// A new endpoint (a new "socket"); the hub keeps working if it outlives us.
  std::shared_ptr<Endpoint> open(const std::string& name);

  /// Fault injection: the whole bus is bus-off for `duration` (every
  /// endpoint fails to send and receives nothing, frames in flight are lost).
  void setBusOff(Duration duration);
  /// Fault injection: one endpoint's controller is bus-off for `duration`.
  void setBusOff(const Endpoint& endpoint, Duration duration);
  /// Fault injection: drop the next `count` sent frames for which `match`
  /// returns true (all frames when `match` is empty).
  void dropNext(int count, std::function<bool(const can_frame&)> match = {});
  /// Fault injection: drop each sent frame with probability `p` (seeded).
  void setDropProbability(double p, std::uint32_t seed = 1);
  /// Frames dropped by injection so far.
  std::uint64_t dropped() const;
  /// Frames sent on the hub so far (all endpoints).
  std::uint64_t sent() const;

 private:
  std::shared_ptr<Hub> hub_;
};

}  // namespace massage_cell::can
