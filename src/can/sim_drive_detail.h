// Private to the SimDrive implementation (sim_drive*.cpp): shared constants,
// the CiA 301 error register, and the controlword / statusword bits of the
// drive state machine that cia402.h's cw:: / sw:: do not name.
#pragma once

#include <cstdint>

#include "massage_cell/can/cia402.h"
#include "massage_cell/can/object_dictionary.h"

namespace massage_cell::can::sim_drive_detail {

using A = ObjectDictionary::Access;
constexpr std::uint32_t kPdoInvalid = 0x80000000u;  // COB-ID bit 31: PDO not valid

/// The CiA 301 error register (0x1001) for an EMCY error code: generic, plus
/// current / voltage / temperature / communication / manufacturer-specific.
inline std::uint8_t errorRegisterFor(std::uint16_t code) {
  std::uint8_t reg = 0x01;  // generic
  switch (code >> 12) {
    case 0x2:
      reg |= 0x02;
      break;
    case 0x3:
      reg |= 0x04;
      break;
    case 0x4:
      reg |= 0x08;
      break;
    default:
      break;
  }
  if ((code & 0xFF00) == 0x8100) reg |= 0x10;
  if ((code & 0xFF00) == 0xFF00) reg |= 0x80;
  return reg;
}

// Controlword bits 0..3 (CiA 402-2 §8.4.1) that select the state-machine
// command; cw:: has the commands themselves (kShutdown, kSwitchOn, ...).
namespace cw_bit {
constexpr std::uint16_t kSwitchOn = 1u << 0;
constexpr std::uint16_t kEnableVoltage = 1u << 1;
constexpr std::uint16_t kQuickStop = 1u << 2;  ///< 0 = quick stop
constexpr std::uint16_t kEnableOperation = 1u << 3;
constexpr std::uint16_t kCommandMask = kSwitchOn | kEnableVoltage | kQuickStop | kEnableOperation;
}  // namespace cw_bit

// Statusword state bits 0..3, 5, 6 (CiA 402-2 §8.4.1); sw:: has bit 4
// (voltage enabled) and the mode bits.
namespace sw_bit {
constexpr std::uint16_t kReadyToSwitchOn = 1u << 0;
constexpr std::uint16_t kSwitchedOn = 1u << 1;
constexpr std::uint16_t kOperationEnabled = 1u << 2;
constexpr std::uint16_t kFault = 1u << 3;
constexpr std::uint16_t kQuickStop = 1u << 5;  ///< 0 = quick stop active
constexpr std::uint16_t kSwitchOnDisabled = 1u << 6;
}  // namespace sw_bit

}  // namespace massage_cell::can::sim_drive_detail
