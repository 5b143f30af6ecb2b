// A CANopen object dictionary (CiA 301 §7.4) for the simulated drive: typed
// entries of fixed size (or variable-length strings), access rights, PDO
// mappability, and SDO-style read / write that return CiA 301 abort codes
// (0 = success) instead of throwing.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace massage_cell::can {

class ObjectDictionary {
 public:
  enum class Access { kReadOnly, kWriteOnly, kReadWrite, kConst };

  struct Entry {
    Access access = Access::kReadWrite;
    std::size_t size = 0;  ///< bytes; 0 = variable length (VISIBLE_STRING / DOMAIN)
    bool is_signed = false;
    bool mappable = false;  ///< may be mapped into a PDO
    std::vector<std::uint8_t> value;
  };

  /// Called before a client write is stored; returns an abort code to refuse it (0 = accept).
  using WriteHook =
      std::function<std::uint32_t(std::uint16_t index, std::uint8_t sub, const std::vector<std::uint8_t>&)>;

  /// Adds (or replaces) an integer entry of `size` bytes (1, 2, 4).
  void add(std::uint16_t index, std::uint8_t sub, Access access, std::size_t size, std::int64_t value,
           bool is_signed = false, bool mappable = false);
  /// Adds a VISIBLE_STRING entry.
  void addString(std::uint16_t index, std::uint8_t sub, Access access, const std::string& value);

  bool has(std::uint16_t index, std::uint8_t sub) const;
  bool hasIndex(std::uint16_t index) const;
  const Entry* find(std::uint16_t index, std::uint8_t sub) const;

  /// SDO upload semantics: 0 or an abort code (object / sub-index missing, write-only).
  std::uint32_t read(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t>& out) const;
  /// SDO download semantics: access, length (0x06070010/12/13), the write hook; 0 on success.
  std::uint32_t write(std::uint16_t index, std::uint8_t sub, const std::vector<std::uint8_t>& data);
  void setWriteHook(WriteHook hook) { hook_ = std::move(hook); }

  /// Device-internal access (no access checks): value as integer (sign-extended when signed).
  std::int64_t get(std::uint16_t index, std::uint8_t sub) const;
  void set(std::uint16_t index, std::uint8_t sub, std::int64_t value);
  std::string getString(std::uint16_t index, std::uint8_t sub) const;

 private:
  std::map<std::uint32_t, Entry> entries_;
  WriteHook hook_;
};

}  // namespace massage_cell::can
