// SDO client state machine (see sdo_client.h).
#include "massage_cell/can/sdo_client.h"

#include <cstdio>

namespace massage_cell::can {

namespace {

std::string objectName(std::uint16_t index, std::uint8_t sub) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%04X:%02X", index, sub);
  return buf;
}

std::string hex8(std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%08X", v);
  return buf;
}

}  // namespace

SdoClient::SdoClient(std::uint8_t node, Send send, const Clock& clock, Duration timeout)
    : node_(node), send_(std::move(send)), clock_(clock), timeout_(timeout) {}

void SdoClient::upload(std::uint16_t index, std::uint8_t sub, Callback done) {
  queue_.push_back(Transfer{true, index, sub, {}, std::move(done)});
  if (!active_) startNext();
}

void SdoClient::download(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data, Callback done) {
  queue_.push_back(Transfer{false, index, sub, std::move(data), std::move(done)});
  if (!active_) startNext();
}

std::string SdoClient::what() const {
  return "node " + std::to_string(node_) + ": SDO " + (current_.upload ? "upload " : "download ") +
         objectName(current_.index, current_.sub);
}

bool SdoClient::sendFrame(const can_frame& f) {
  deadline_ = clock_.now() + timeout_;
  return send_(f);
}

void SdoClient::startNext() {
  if (quarantine_ && clock_.now() >= quarantine_until_) quarantine_ = false;
  while (!active_ && !quarantine_ && !queue_.empty()) {
    current_ = std::move(queue_.front());
    queue_.pop_front();
    active_ = true;
    phase_ = Phase::kInitiate;
    toggle_ = false;
    offset_ = 0;
    expected_size_ = 0;
    size_known_ = false;
    if (!current_.upload && current_.data.empty()) {
      fail(sdo_abort::kLengthTooLow, "nothing to download", false);
      continue;
    }
    const can_frame f = current_.upload
                            ? sdoInitiateUploadRequest(node_, current_.index, current_.sub)
                            : sdoInitiateDownloadRequest(node_, current_.index, current_.sub, current_.data);
    // A frame the bus refused is handled like a lost one: the response timeout fires.
    sendFrame(f);
  }
}

void SdoClient::finish(SdoResult result) {
  Callback done = std::move(current_.done);
  active_ = false;
  current_ = Transfer{};
  if (done) done(result);
  if (!active_) startNext();
}

void SdoClient::fail(std::uint32_t code, const std::string& why, bool send_abort) {
  if (send_abort) send_(sdoAbortRequest(node_, current_.index, current_.sub, code));
  SdoResult r;
  r.abort_code = code;
  r.error = what() + ": " + why;
  finish(std::move(r));
}

void SdoClient::sendNextDownloadSegment() {
  const std::size_t n = std::min<std::size_t>(7, current_.data.size() - offset_);
  const std::vector<std::uint8_t> chunk(current_.data.begin() + static_cast<std::ptrdiff_t>(offset_),
                                        current_.data.begin() + static_cast<std::ptrdiff_t>(offset_ + n));
  const bool last = offset_ + n >= current_.data.size();
  offset_ += n;
  sendFrame(sdoDownloadSegmentRequest(node_, toggle_, chunk, last));
}

bool SdoClient::handle(const SdoFrame& r) {
  if (r.node != node_) return false;
  if (quarantine_) {
    // The late answer to a transfer we cancelled: drop it, then carry on.
    quarantine_ = false;
    if (!active_) startNext();
    return true;
  }
  if (!active_) return false;
  if (r.command == SdoCommand::kAbort) {
    // An abort ends our transfer even when it names another object (one SDO channel per node).
    SdoResult res;
    res.abort_code = r.abort_code;
    res.error = what() + ": aborted by the server: " + hex8(r.abort_code) + " " + sdoAbortText(r.abort_code);
    finish(std::move(res));
    return true;
  }
  if (phase_ == Phase::kInitiate) {
    const SdoCommand want = current_.upload ? SdoCommand::kInitiateUpload : SdoCommand::kInitiateDownload;
    if (r.command != want) {
      fail(sdo_abort::kCommandSpecifier, std::string("unexpected ") + toString(r.command) + " response", true);
      return true;
    }
    if (r.index != current_.index || r.subindex != current_.sub) {
      fail(sdo_abort::kGeneral, "response names object " + objectName(r.index, r.subindex), true);
      return true;
    }
    if (current_.upload) {
      if (r.expedited) {
        SdoResult res;
        res.ok = true;
        res.data = r.data;
        finish(std::move(res));
        return true;
      }
      size_known_ = r.size_indicated;
      expected_size_ = r.size;
      current_.data.clear();
      phase_ = Phase::kSegment;
      toggle_ = false;
      sendFrame(sdoUploadSegmentRequest(node_, toggle_));
      return true;
    }
    if (current_.data.size() <= 4) {  // expedited download confirmed
      SdoResult res;
      res.ok = true;
      finish(std::move(res));
      return true;
    }
    phase_ = Phase::kSegment;
    toggle_ = false;
    sendNextDownloadSegment();
    return true;
  }
  // Segment phase.
  if (current_.upload) {
    if (r.command != SdoCommand::kUploadSegment) {
      fail(sdo_abort::kCommandSpecifier, std::string("unexpected ") + toString(r.command) + " response", true);
      return true;
    }
    if (r.toggle != toggle_) {
      fail(sdo_abort::kToggleBit, "toggle bit not alternated", true);
      return true;
    }
    current_.data.insert(current_.data.end(), r.data.begin(), r.data.end());
    if (size_known_ && current_.data.size() > expected_size_) {
      fail(sdo_abort::kLengthTooHigh, "more data than the announced " + std::to_string(expected_size_) + " bytes",
           true);
      return true;
    }
    if (r.last) {
      if (size_known_ && current_.data.size() != expected_size_) {
        fail(sdo_abort::kLengthMismatch,
             "received " + std::to_string(current_.data.size()) + " of the announced " +
                 std::to_string(expected_size_) + " bytes",
             true);
        return true;
      }
      SdoResult res;
      res.ok = true;
      res.data = std::move(current_.data);
      finish(std::move(res));
      return true;
    }
    toggle_ = !toggle_;
    sendFrame(sdoUploadSegmentRequest(node_, toggle_));
    return true;
  }
  if (r.command != SdoCommand::kDownloadSegment) {
    fail(sdo_abort::kCommandSpecifier, std::string("unexpected ") + toString(r.command) + " response", true);
    return true;
  }
  if (r.toggle != toggle_) {
    fail(sdo_abort::kToggleBit, "toggle bit not alternated", true);
    return true;
  }
  if (offset_ >= current_.data.size()) {
    SdoResult res;
    res.ok = true;
    finish(std::move(res));
    return true;
  }
  toggle_ = !toggle_;
  sendNextDownloadSegment();
  return true;
}

void SdoClient::poll() {
  if (active_ && clock_.now() >= deadline_) {
    fail(sdo_abort::kTimeout,
         "no response within " + std::to_string(static_cast<long long>(toMs(timeout_))) + " ms (" +
             sdoAbortText(sdo_abort::kTimeout) + ")",
         true);
  }
  if (!active_) startNext();
}

void SdoClient::cancelAll(const std::string& reason) {
  std::deque<Transfer> pending;
  pending.swap(queue_);
  if (active_) {
    // The server may still answer the request in flight: tell it to stop and
    // ignore one late response (up to one timeout) before the next transfer.
    send_(sdoAbortRequest(node_, current_.index, current_.sub, sdo_abort::kGeneral));
    quarantine_ = true;
    quarantine_until_ = clock_.now() + timeout_;
    SdoResult r;
    r.abort_code = sdo_abort::kGeneral;
    r.error = what() + ": " + reason;
    Callback done = std::move(current_.done);
    active_ = false;
    current_ = Transfer{};
    if (done) done(r);
  }
  for (Transfer& t : pending) {
    SdoResult r;
    r.abort_code = sdo_abort::kGeneral;
    r.error = "node " + std::to_string(node_) + ": SDO " + (t.upload ? "upload " : "download ") +
              objectName(t.index, t.sub) + ": " + reason;
    if (t.done) t.done(r);
  }
}

}  // namespace massage_cell::can
