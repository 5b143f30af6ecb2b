// Object dictionary of the simulated drive (see object_dictionary.h).
#include "massage_cell/can/object_dictionary.h"

#include <stdexcept>

#include "massage_cell/can/canopen.h"

namespace massage_cell::can {

namespace {
std::uint32_t key(std::uint16_t index, std::uint8_t sub) { return (static_cast<std::uint32_t>(index) << 8) | sub; }
}  // namespace

void ObjectDictionary::add(std::uint16_t index, std::uint8_t sub, Access access, std::size_t size, std::int64_t value,
                           bool is_signed, bool mappable) {
  if (size != 1 && size != 2 && size != 4 && size != 8) throw std::invalid_argument("ObjectDictionary::add: bad size");
  Entry e;
  e.access = access;
  e.size = size;
  e.is_signed = is_signed;
  e.mappable = mappable;
  e.value = toBytes(static_cast<std::uint64_t>(value), size);
  entries_[key(index, sub)] = e;
}

void ObjectDictionary::addString(std::uint16_t index, std::uint8_t sub, Access access, const std::string& value) {
  Entry e;
  e.access = access;
  e.size = 0;
  e.value.assign(value.begin(), value.end());
  entries_[key(index, sub)] = e;
}

bool ObjectDictionary::has(std::uint16_t index, std::uint8_t sub) const { return entries_.count(key(index, sub)) != 0; }

bool ObjectDictionary::hasIndex(std::uint16_t index) const {
  auto it = entries_.lower_bound(key(index, 0));
  return it != entries_.end() && (it->first >> 8) == index;
}

const ObjectDictionary::Entry* ObjectDictionary::find(std::uint16_t index, std::uint8_t sub) const {
  auto it = entries_.find(key(index, sub));
  return it == entries_.end() ? nullptr : &it->second;
}

std::uint32_t ObjectDictionary::read(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t>& out) const {
  const Entry* e = find(index, sub);
  if (!e) return hasIndex(index) ? sdo_abort::kNoSubIndex : sdo_abort::kNoObject;
  if (e->access == Access::kWriteOnly) return sdo_abort::kWriteOnly;
  out = e->value;
  if (out.empty()) return sdo_abort::kGeneral + 0x24;  // 0x08000024 no data available
  return 0;
}

std::uint32_t ObjectDictionary::write(std::uint16_t index, std::uint8_t sub, const std::vector<std::uint8_t>& data) {
  auto it = entries_.find(key(index, sub));
  if (it == entries_.end()) return hasIndex(index) ? sdo_abort::kNoSubIndex : sdo_abort::kNoObject;
  Entry& e = it->second;
  if (e.access == Access::kReadOnly || e.access == Access::kConst) return sdo_abort::kReadOnly;
  if (e.size != 0 && data.size() != e.size) {
    return data.size() > e.size ? sdo_abort::kLengthTooHigh : sdo_abort::kLengthTooLow;
  }
  if (hook_) {
    if (const std::uint32_t code = hook_(index, sub, data)) return code;
  }
  e.value = data;
  return 0;
}

std::int64_t ObjectDictionary::get(std::uint16_t index, std::uint8_t sub) const {
  const Entry* e = find(index, sub);
  if (!e)
    throw std::out_of_range("ObjectDictionary::get: no object " + std::to_string(index) + ":" + std::to_string(sub));
  const std::uint64_t v = fromBytes(e->value);
  return e->is_signed ? signExtend(v, static_cast<unsigned>(e->size * 8)) : static_cast<std::int64_t>(v);
}

void ObjectDictionary::set(std::uint16_t index, std::uint8_t sub, std::int64_t value) {
  auto it = entries_.find(key(index, sub));
  if (it == entries_.end()) {
    throw std::out_of_range("ObjectDictionary::set: no object " + std::to_string(index) + ":" + std::to_string(sub));
  }
  it->second.value = toBytes(static_cast<std::uint64_t>(value), it->second.size ? it->second.size : 4);
}

std::string ObjectDictionary::getString(std::uint16_t index, std::uint8_t sub) const {
  const Entry* e = find(index, sub);
  return e ? std::string(e->value.begin(), e->value.end()) : std::string();
}

}  // namespace massage_cell::can
