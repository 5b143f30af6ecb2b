// Linux SocketCAN endpoint (layer 1): a PF_CAN / SOCK_RAW / CAN_RAW socket
// bound to one interface (can0, vcan0, ...), non-blocking with ppoll,
// CAN_RAW_FILTER receive filters, CAN_RAW_ERR_FILTER error frames decoded into
// the bus state (linux/can/error.h: CAN_ERR_BUSOFF, CAN_ERR_CRTL warning /
// passive / active, CAN_ERR_RESTARTED), SO_TIMESTAMP receive stamps, and
// automatic recovery from bus-off or a downed interface: the socket is closed
// and reopened with exponential back-off until the interface is up and
// running again. (On real controllers the kernel restarts a bus-off
// controller by itself only when `ip link set canX type can restart-ms N` was
// set; with restart-ms 0 an operator has to run `ip link set canX type can
// restart`; until then the interface has no carrier and reopening keeps
// backing off.)
#pragma once

#include <linux/can/error.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <shared_mutex>

#include "massage_cell/can/bus.h"

namespace massage_cell::can {

/// Options of a SocketCanBus.
struct SocketCanOptions {
  std::string interface;                                     ///< e.g. "can0", "vcan0"
  std::vector<can_filter> filters = acceptAllFilters();      ///< CAN_RAW_FILTER
  can_err_mask_t error_mask = CAN_ERR_MASK;                  ///< CAN_RAW_ERR_FILTER
  bool loopback = true;                                      ///< CAN_RAW_LOOPBACK
  bool receive_own = false;                                  ///< CAN_RAW_RECV_OWN_MSGS
  Duration reopen_initial = std::chrono::milliseconds(100);  ///< first back-off after bus-off / down
  Duration reopen_max = std::chrono::seconds(5);             ///< back-off cap
};

/// What one error frame (CAN_ERR_FLAG set) says.
struct ErrorFrameInfo {
  bool valid = false;             ///< it was an error frame
  std::optional<BusState> state;  ///< new controller state, when the frame reports one
  std::string text;               ///< "bus-off; controller: rx error-passive; ..."
};
/// Decodes an error frame of the Linux CAN error API (linux/can/error.h).
ErrorFrameInfo decodeErrorFrame(const can_frame& frame);

/// Exponential back-off: initial, 2x, 4x, ... capped at max.
class Backoff {
 public:
  Backoff(Duration initial, Duration max) : initial_(initial), max_(max), next_(initial) {}
  /// The delay to wait now; doubles the following one.
  Duration next();
  void reset() { next_ = initial_; }

 private:
  Duration initial_, max_, next_;
};

/// One CAN_RAW socket; see the file comment.
class SocketCanBus final : public Bus {
 public:
  /// Opens and binds the socket; throws BusError naming the interface when it
  /// does not exist or the socket cannot be set up.
  explicit SocketCanBus(SocketCanOptions options);
  ~SocketCanBus() override;
  SocketCanBus(const SocketCanBus&) = delete;
  SocketCanBus& operator=(const SocketCanBus&) = delete;

  std::string name() const override { return options_.interface; }
  bool send(const can_frame& frame) override;
  std::optional<TimedFrame> receive(Duration timeout) override;
  void setFilters(const std::vector<can_filter>& filters) override;
  BusStatus status() const override;

 private:
  int openSocket();  // throws BusError
  void requestReopen(const std::string& reason, BusState state);
  bool reopenIfDue();  // true when a socket is open
  void noteState(BusState state, const std::string& text);

  SocketCanOptions options_;
  mutable std::shared_mutex fd_mutex_;  // shared: I/O; unique: close / reopen
  int fd_ = -1;
  std::atomic<bool> reopen_requested_{false};
  mutable std::mutex status_mutex_;
  BusStatus status_;
  Backoff backoff_;
  TimePoint next_reopen_{};
  TimePoint active_since_{};
};

}  // namespace massage_cell::can
