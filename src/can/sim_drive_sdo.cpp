// SimDrive, SDO server (see sim_drive.h): expedited and segmented upload /
// download, aborts with CiA 301 codes, delayed and dropped responses.
#include "massage_cell/can/sim_drive.h"

#include <algorithm>

#include "sim_drive_detail.h"

namespace massage_cell::can {

using namespace sim_drive_detail;

void SimDrive::respondSdo(const can_frame& f, TimePoint now) {
  if (sdo_drop_ > 0) {
    --sdo_drop_;
    ++stats_.sdo_dropped;
    return;
  }
  if (sdo_delay_ > Duration::zero() || !pending_sdo_.empty()) {
    pending_sdo_.push_back({now + sdo_delay_, f});
    return;
  }
  send(f);
}

void SimDrive::abortSdo(std::uint16_t index, std::uint8_t sub, std::uint32_t code, TimePoint now) {
  upload_ = {};
  download_ = {};
  ++stats_.sdo_aborts;
  respondSdo(sdoAbortResponse(config_.node_id, index, sub, code), now);
}

void SimDrive::handleSdo(const SdoFrame& r, TimePoint now) {
  ++stats_.sdo_requests;
  switch (r.command) {
    case SdoCommand::kAbort:
      upload_ = {};
      download_ = {};
      pending_sdo_.clear();  // the client gave up: late answers would confuse it
      return;
    case SdoCommand::kInitiateUpload:
      return sdoInitiateUpload(r, now);
    case SdoCommand::kUploadSegment:
      return sdoUploadSegment(r, now);
    case SdoCommand::kInitiateDownload:
      return sdoInitiateDownload(r, now);
    case SdoCommand::kDownloadSegment:
      return sdoDownloadSegment(r, now);
  }
}

void SimDrive::sdoInitiateUpload(const SdoFrame& r, TimePoint now) {
  upload_ = {};
  download_ = {};
  updateProcessObjects();
  std::vector<std::uint8_t> data;
  if (const std::uint32_t code = od_.read(r.index, r.subindex, data)) return abortSdo(r.index, r.subindex, code, now);
  if (data.size() > 4) {
    upload_.active = true;
    upload_.index = r.index;
    upload_.sub = r.subindex;
    upload_.data = data;
  }
  respondSdo(sdoInitiateUploadResponse(config_.node_id, r.index, r.subindex, data), now);
}

void SimDrive::sdoUploadSegment(const SdoFrame& r, TimePoint now) {
  if (!upload_.active) return abortSdo(0, 0, sdo_abort::kCommandSpecifier, now);
  if (r.toggle != upload_.toggle) return abortSdo(upload_.index, upload_.sub, sdo_abort::kToggleBit, now);
  const std::size_t n = std::min<std::size_t>(7, upload_.data.size() - upload_.offset);
  const std::vector<std::uint8_t> chunk(upload_.data.begin() + static_cast<std::ptrdiff_t>(upload_.offset),
                                        upload_.data.begin() + static_cast<std::ptrdiff_t>(upload_.offset + n));
  upload_.offset += n;
  const bool last = upload_.offset >= upload_.data.size();
  const bool t = upload_.toggle;
  upload_.toggle = !upload_.toggle;
  if (last) upload_ = {};
  respondSdo(sdoUploadSegmentResponse(config_.node_id, t, chunk, last), now);
}

void SimDrive::sdoInitiateDownload(const SdoFrame& r, TimePoint now) {
  const std::uint8_t id = config_.node_id;
  upload_ = {};
  download_ = {};
  if (r.expedited) {
    if (const std::uint32_t code = od_.write(r.index, r.subindex, r.data))
      return abortSdo(r.index, r.subindex, code, now);
    afterWrite(r.index, r.subindex);
    return respondSdo(sdoInitiateDownloadResponse(id, r.index, r.subindex), now);
  }
  const ObjectDictionary::Entry* e = od_.find(r.index, r.subindex);
  if (!e) {
    return abortSdo(r.index, r.subindex, od_.hasIndex(r.index) ? sdo_abort::kNoSubIndex : sdo_abort::kNoObject, now);
  }
  if (e->access == A::kReadOnly || e->access == A::kConst)
    return abortSdo(r.index, r.subindex, sdo_abort::kReadOnly, now);
  if (r.size_indicated && e->size != 0 && r.size != e->size) {
    return abortSdo(r.index, r.subindex, r.size > e->size ? sdo_abort::kLengthTooHigh : sdo_abort::kLengthTooLow, now);
  }
  download_.active = true;
  download_.index = r.index;
  download_.sub = r.subindex;
  download_.size = r.size;
  download_.size_known = r.size_indicated;
  respondSdo(sdoInitiateDownloadResponse(id, r.index, r.subindex), now);
}

void SimDrive::sdoDownloadSegment(const SdoFrame& r, TimePoint now) {
  if (!download_.active) return abortSdo(0, 0, sdo_abort::kCommandSpecifier, now);
  if (r.toggle != download_.toggle) return abortSdo(download_.index, download_.sub, sdo_abort::kToggleBit, now);
  download_.data.insert(download_.data.end(), r.data.begin(), r.data.end());
  if (download_.size_known && download_.data.size() > download_.size) {
    return abortSdo(download_.index, download_.sub, sdo_abort::kLengthTooHigh, now);
  }
  const bool t = download_.toggle;
  download_.toggle = !download_.toggle;
  if (r.last) {
    const Download d = download_;
    download_ = {};
    if (d.size_known && d.data.size() != d.size) return abortSdo(d.index, d.sub, sdo_abort::kLengthMismatch, now);
    if (const std::uint32_t code = od_.write(d.index, d.sub, d.data)) return abortSdo(d.index, d.sub, code, now);
    afterWrite(d.index, d.sub);
  }
  respondSdo(sdoDownloadSegmentResponse(config_.node_id, t), now);
}

}  // namespace massage_cell::can
