// Frame helpers and filter semantics shared by every Bus (see bus.h).
#include "massage_cell/can/bus.h"

#include <cstdio>
#include <cstring>

namespace massage_cell::can {

const char* toString(BusState state) {
  switch (state) {
    case BusState::kErrorActive:
      return "error-active";
    case BusState::kErrorWarning:
      return "error-warning";
    case BusState::kErrorPassive:
      return "error-passive";
    case BusState::kBusOff:
      return "bus-off";
    case BusState::kDown:
      return "down";
  }
  return "unknown";
}

bool matchesFilter(const can_frame& frame, const can_filter& filter) {
  if (frame.can_id & CAN_ERR_FLAG) return false;
  const bool inverted = (filter.can_id & CAN_INV_FILTER) != 0;
  const canid_t fid = filter.can_id & ~CAN_INV_FILTER;
  const bool match = (frame.can_id & filter.can_mask) == (fid & filter.can_mask);
  return inverted ? !match : match;
}

bool matchesFilters(const can_frame& frame, const std::vector<can_filter>& filters) {
  for (const can_filter& f : filters) {
    if (matchesFilter(frame, f)) return true;
  }
  return false;
}

std::vector<can_filter> acceptAllFilters() { return {can_filter{0, 0}}; }

can_frame makeFrame(canid_t id, const std::vector<std::uint8_t>& data) {
  if (data.size() > CAN_MAX_DLEN) throw std::invalid_argument("makeFrame: more than 8 data bytes");
  can_frame f{};
  const bool eff = (id & CAN_EFF_FLAG) || (id & CAN_EFF_MASK) > CAN_SFF_MASK;
  f.can_id = eff ? ((id & CAN_EFF_MASK) | CAN_EFF_FLAG) : (id & CAN_SFF_MASK);
  f.can_id |= id & CAN_RTR_FLAG;
  f.len = static_cast<std::uint8_t>(data.size());
  if (!data.empty()) std::memcpy(f.data, data.data(), data.size());  // data() may be null when empty
  return f;
}

can_frame makeFrame(canid_t id, std::initializer_list<std::uint8_t> data) {
  return makeFrame(id, std::vector<std::uint8_t>(data));
}

std::string formatFrame(const can_frame& frame) {
  char buf[64];
  int n;
  if (frame.can_id & CAN_ERR_FLAG) {
    n = std::snprintf(buf, sizeof buf, "ERR:%08X#", frame.can_id & CAN_ERR_MASK);
  } else if (frame.can_id & CAN_EFF_FLAG) {
    n = std::snprintf(buf, sizeof buf, "%08X#", frame.can_id & CAN_EFF_MASK);
  } else {
    n = std::snprintf(buf, sizeof buf, "%03X#", frame.can_id & CAN_SFF_MASK);
  }
  std::string out(buf, static_cast<std::size_t>(n));
  if (frame.can_id & CAN_RTR_FLAG) return out + "R";
  const int len = frame.len > CAN_MAX_DLEN ? CAN_MAX_DLEN : frame.len;
  for (int i = 0; i < len; ++i) {
    std::snprintf(buf, sizeof buf, "%02X", frame.data[i]);
    out += buf;
  }
  return out;
}

bool sameFrame(const can_frame& a, const can_frame& b) {
  if (a.can_id != b.can_id || a.len != b.len) return false;
  const int len = a.len > CAN_MAX_DLEN ? CAN_MAX_DLEN : a.len;
  return std::memcmp(a.data, b.data, static_cast<std::size_t>(len)) == 0;
}

}  // namespace massage_cell::can
