// SDO client of one node (layer 3; CiA 301 §7.2.4.3): expedited and
// segmented upload / download, one transfer at a time, the rest queued in
// order. Every wait for a server response times out after `timeout` (the
// client then sends abort 0x05040000 "SDO protocol timed out"); a server
// abort, a toggle error, a wrong command specifier or a response to another
// object fail the transfer with a message naming node, object and cause.
// Driven by handle() (responses) and poll() (time); not thread-safe by
// itself (the Master serialises access).
#pragma once

#include <deque>
#include <functional>

#include "massage_cell/can/canopen.h"
#include "massage_cell/can/clock.h"

namespace massage_cell::can {

/// Outcome of one SDO transfer.
struct SdoResult {
  bool ok = false;
  std::vector<std::uint8_t> data;  ///< uploaded bytes
  std::uint32_t abort_code = 0;    ///< server's or our own abort code on failure
  std::string error;  ///< "node 1: SDO upload 0x6041:00 aborted by the server: 0x06020000 object does not exist ..."
};

class SdoClient {
 public:
  using Send = std::function<bool(const can_frame&)>;
  using Callback = std::function<void(const SdoResult&)>;

  SdoClient(std::uint8_t node, Send send, const Clock& clock, Duration timeout);

  /// Queues an upload (read) of index:sub; `done` runs exactly once.
  void upload(std::uint16_t index, std::uint8_t sub, Callback done);
  /// Queues a download (write); expedited for 1..4 bytes, else segmented.
  void download(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data, Callback done);
  /// Feeds a decoded server response for this node; false when unexpected
  /// (no transfer running: ignored).
  bool handle(const SdoFrame& response);
  /// Timeouts, and starts the next queued transfer.
  void poll();
  /// Fails the running and queued transfers with `reason`. A running one is
  /// aborted on the bus (0x08000000) and one late response to it, if any
  /// arrives within a timeout, is dropped before the next transfer starts.
  void cancelAll(const std::string& reason);
  bool busy() const { return active_; }
  std::size_t queued() const { return queue_.size(); }
  std::uint8_t node() const { return node_; }
  void setTimeout(Duration timeout) { timeout_ = timeout; }

 private:
  struct Transfer {
    bool upload = true;
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    std::vector<std::uint8_t> data;  // download: to send; upload: received
    Callback done;
  };
  enum class Phase { kInitiate, kSegment };

  void startNext();
  void finish(SdoResult result);
  void fail(std::uint32_t code, const std::string& why, bool send_abort);
  std::string what() const;
  bool sendFrame(const can_frame& f);
  void sendNextDownloadSegment();

  std::uint8_t node_;
  Send send_;
  const Clock& clock_;
  Duration timeout_;
  std::deque<Transfer> queue_;
  bool active_ = false;
  Transfer current_;
  Phase phase_ = Phase::kInitiate;
  bool toggle_ = false;
  std::size_t offset_ = 0;  // download: bytes sent; upload: expected size
  std::uint32_t expected_size_ = 0;
  bool size_known_ = false;
  TimePoint deadline_{};
  bool quarantine_ = false;  // a cancelled request may still be answered
  TimePoint quarantine_until_{};
};

}  // namespace massage_cell::can
