// CAN bus abstraction (layer 1 of the motion stack, below CANopen): one
// endpoint on a CAN bus that sends and receives classic CAN frames
// (`struct can_frame` of linux/can.h), with SocketCAN's filter semantics and
// an error-state report (ISO 11898-1 fault confinement: error-active,
// error-passive, bus-off). Implementations: VirtualBus endpoints (in-process,
// tests and benches) and SocketCanBus (Linux SocketCAN).
#pragma once

#include <linux/can.h>

#include <cstdint>
#include <initializer_list>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "massage_cell/can/clock.h"

namespace massage_cell::can {

/// Setup failures of a bus (interface missing, socket errors): the message
/// names the interface and the failing call.
class BusError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A received frame and its receive time (on the bus's clock: the VirtualBus
/// clock, or the kernel's SO_TIMESTAMP moved onto the steady clock).
struct TimedFrame {
  can_frame frame{};
  TimePoint stamp{};
};

/// ISO 11898-1 fault confinement state of the endpoint's controller, plus
/// `kDown` (the interface/socket is not usable, e.g. being reopened).
enum class BusState { kErrorActive, kErrorWarning, kErrorPassive, kBusOff, kDown };

/// "error-active", "error-warning", "error-passive", "bus-off", "down".
const char* toString(BusState state);

/// Counters and state of one endpoint.
struct BusStatus {
  BusState state = BusState::kErrorActive;
  std::uint64_t tx_frames = 0;       ///< frames accepted for transmission
  std::uint64_t tx_failed = 0;       ///< send() calls that returned false
  std::uint64_t rx_frames = 0;       ///< frames returned by receive()
  std::uint64_t rx_overflow = 0;     ///< frames lost because the receive queue was full
  std::uint64_t error_frames = 0;    ///< error frames / error events seen
  std::uint64_t bus_off_events = 0;  ///< transitions into bus-off
  std::uint64_t recoveries = 0;      ///< transitions out of bus-off / down back to error-active
  std::string last_error;            ///< human-readable description of the last problem
};

/// One endpoint on a CAN bus (think: one CAN_RAW socket).
class Bus {
 public:
  virtual ~Bus() = default;
  /// Name for messages (interface or endpoint name).
  virtual std::string name() const = 0;
  /// Transmits one frame; false when it was not sent (bus-off, interface
  /// down, queue full): status().last_error says why. Never throws.
  virtual bool send(const can_frame& frame) = 0;
  /// The next received frame that passes the filters, waiting up to
  /// `timeout` of real time (0 = just poll); nullopt when none arrived.
  virtual std::optional<TimedFrame> receive(Duration timeout) = 0;
  /// Replaces the receive filters (CAN_RAW_FILTER semantics: a frame passes
  /// when it matches any filter; an empty list receives nothing).
  virtual void setFilters(const std::vector<can_filter>& filters) = 0;
  /// Current state and counters.
  virtual BusStatus status() const = 0;
};

/// CAN_RAW_FILTER match of one filter: (id & mask) == (filter.id & mask),
/// inverted when CAN_INV_FILTER is set in filter.can_id; error frames never
/// match (they go through the error mask).
bool matchesFilter(const can_frame& frame, const can_filter& filter);
/// Any of the filters matches.
bool matchesFilters(const can_frame& frame, const std::vector<can_filter>& filters);
/// The default filter set of a CAN_RAW socket: everything.
std::vector<can_filter> acceptAllFilters();

/// A data frame with a standard (11-bit) id, or extended when id > 0x7FF or
/// CAN_EFF_FLAG is given; throws std::invalid_argument for more than 8 bytes.
can_frame makeFrame(canid_t id, std::initializer_list<std::uint8_t> data);
can_frame makeFrame(canid_t id, const std::vector<std::uint8_t>& data);
/// candump-style text: "181#2700E8030000" / "12345678#..." / "080#R".
std::string formatFrame(const can_frame& frame);
/// Same id, flags, DLC and payload bytes.
bool sameFrame(const can_frame& a, const can_frame& b);

}  // namespace massage_cell::can
