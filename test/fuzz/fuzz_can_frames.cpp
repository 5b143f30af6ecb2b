// Fuzz target: the CiA 301 frame codecs (canopen.h) on arbitrary frames —
// ids of every width and flag, DLCs up to 15, any payload — and the PDO
// packer on arbitrary mappings. Each decoder either fails with a reason or
// returns a value within its documented ranges; a PDO packed and unpacked
// again gives back its values' low bits.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include "fuzz_input.h"
#include "massage_cell/can/canopen.h"

using namespace massage_cell::can;

namespace {

[[noreturn]] void broken(const std::string& what) {
  std::cerr << "fuzz_can_frames: " << what << "\n";
  std::abort();
}

template <typename T>
void checkFailure(const Result<T>& r, const char* decoder) {
  if (!r && r.error().empty()) broken(std::string(decoder) + " failed without a reason");
}

can_frame frameFrom(massage_cell::fuzz::FuzzInput& in) {
  can_frame f{};
  f.can_id = in.bits<std::uint32_t>();
  if (in.flag()) f.can_id &= CAN_SFF_MASK;  // mostly standard ids, sometimes anything
  f.can_dlc = in.byte() % 16;               // DLCs above 8 must be refused, not read past the payload
  const std::uint64_t payload = in.bits<std::uint64_t>();
  std::memcpy(f.data, &payload, sizeof(payload));
  return f;
}

void decodeAll(const can_frame& f) {
  const auto cob = classify(f);
  checkFailure(cob, "classify");
  if (cob) (void)toString(cob->type);
  checkFailure(decodeNmt(f), "decodeNmt");
  checkFailure(decodeSync(f), "decodeSync");
  const auto hb = decodeHeartbeat(f);
  checkFailure(hb, "decodeHeartbeat");
  if (hb) (void)toString(hb->state);
  const auto emcy = decodeEmcy(f);
  checkFailure(emcy, "decodeEmcy");
  if (emcy) {
    if (!validNodeId(emcy->node)) broken("decodeEmcy gave node " + std::to_string(emcy->node));
    if (emcyText(emcy->emcy.error_code).empty()) broken("emcyText is empty");
  }
  for (const auto& sdo : {decodeSdoRequest(f), decodeSdoResponse(f)}) {
    checkFailure(sdo, "decodeSdo");
    if (!sdo) continue;
    if (!validNodeId(sdo->node)) broken("an SDO frame of node " + std::to_string(sdo->node));
    if (sdo->data.size() > 7) broken("an SDO frame with " + std::to_string(sdo->data.size()) + " data bytes");
    (void)toString(sdo->command);
    if (sdo->command == SdoCommand::kAbort && sdoAbortText(sdo->abort_code).empty()) broken("sdoAbortText is empty");
  }
}

void pdoRoundTrip(massage_cell::fuzz::FuzzInput& in, const can_frame& f) {
  PdoMapping mapping;
  for (int n = in.byte() % 10; n > 0; --n) mapping.push_back(decodeMappingEntry(in.bits<std::uint32_t>()));
  checkFailure(unpackPdo(f, mapping), "unpackPdo");
  const auto bits = mappingBits(mapping);
  checkFailure(bits, "mappingBits");
  std::vector<std::uint64_t> values(mapping.size());
  for (auto& v : values) v = in.bits<std::uint64_t>();
  const auto packed = packPdo(0x180 + 1, mapping, values);
  checkFailure(packed, "packPdo");
  if (!bits || !packed) return;
  const auto unpacked = unpackPdo(*packed, mapping);
  if (!unpacked) broken("unpackPdo refused packPdo's own frame: " + unpacked.error());
  for (std::size_t i = 0; i < mapping.size(); ++i) {
    const unsigned b = mapping[i].bits;
    const std::uint64_t mask = b >= 64 ? ~0ull : ((1ull << b) - 1);
    if ((*unpacked)[i] != (values[i] & mask)) broken("PDO value " + std::to_string(i) + " changed in the round trip");
  }
  (void)signExtend(values.empty() ? 0 : values[0], in.byte() % 70);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  massage_cell::fuzz::FuzzInput in(data, size);
  const can_frame f = frameFrom(in);
  decodeAll(f);
  pdoRoundTrip(in, f);
  std::vector<std::uint8_t> bytes(in.byte() % 12);
  for (auto& b : bytes) b = in.byte();
  (void)fromBytes(bytes);
  return 0;
}
