// Layer 2 tests: CANopen codecs against hand-written CiA 301 byte layouts,
// the error-code / abort-code texts, and malformed frames (never a throw).
#include <gtest/gtest.h>

#include <random>

#include "massage_cell/can/bus.h"
#include "massage_cell/can/canopen.h"

namespace {

using namespace massage_cell::can;

// "601#2B40600000" style frame from hex text (the layouts below are written by hand from CiA 301).
can_frame F(canid_t id, const std::vector<std::uint8_t>& bytes) { return makeFrame(id, bytes); }

void expectFrame(const can_frame& got, const can_frame& want) {
  EXPECT_TRUE(sameFrame(got, want)) << "got " << formatFrame(got) << " want " << formatFrame(want);
}

TEST(Nmt, EncodesCommandAndNode) {
  expectFrame(encodeNmt(NmtCommand::kStart, 5), F(0x000, {0x01, 0x05}));
  expectFrame(encodeNmt(NmtCommand::kStop, 1), F(0x000, {0x02, 0x01}));
  expectFrame(encodeNmt(NmtCommand::kEnterPreOperational, 127), F(0x000, {0x80, 0x7F}));
  expectFrame(encodeNmt(NmtCommand::kResetNode, 3), F(0x000, {0x81, 0x03}));
  expectFrame(encodeNmt(NmtCommand::kResetCommunication, 0), F(0x000, {0x82, 0x00}));
  EXPECT_THROW(encodeNmt(NmtCommand::kStart, 128), std::invalid_argument);
}

TEST(Nmt, DecodesAndRejectsMalformed) {
  auto m = decodeNmt(F(0x000, {0x81, 0x02}));
  ASSERT_TRUE(m) << m.error();
  EXPECT_EQ(m->command, NmtCommand::kResetNode);
  EXPECT_EQ(m->node, 2);
  EXPECT_FALSE(decodeNmt(F(0x000, {0x01})));              // DLC 1
  EXPECT_FALSE(decodeNmt(F(0x000, {0x01, 0x02, 0x03})));  // DLC 3
  EXPECT_FALSE(decodeNmt(F(0x000, {0x03, 0x01})));        // unknown command
  EXPECT_FALSE(decodeNmt(F(0x000, {0x01, 0x80})));        // node 128
  EXPECT_FALSE(decodeNmt(F(0x001, {0x01, 0x01})));        // wrong COB-ID
  EXPECT_NE(decodeNmt(F(0x000, {0x01})).error().find("DLC 1"), std::string::npos);
}

TEST(Sync, WithAndWithoutCounter) {
  expectFrame(encodeSync(), F(0x080, {}));
  expectFrame(encodeSync(7), F(0x080, {0x07}));
  EXPECT_THROW(encodeSync(0), std::invalid_argument);
  EXPECT_THROW(encodeSync(241), std::invalid_argument);
  auto a = decodeSync(F(0x080, {}));
  ASSERT_TRUE(a);
  EXPECT_FALSE(a->has_value());
  auto b = decodeSync(F(0x080, {240}));
  ASSERT_TRUE(b);
  EXPECT_EQ(**b, 240);
  EXPECT_FALSE(decodeSync(F(0x080, {0})));
  EXPECT_FALSE(decodeSync(F(0x080, {1, 2})));
  EXPECT_FALSE(decodeSync(F(0x081, {})));
}

TEST(Heartbeat, BootUpAndStates) {
  expectFrame(encodeHeartbeat(5, NmtState::kBootUp), F(0x705, {0x00}));
  expectFrame(encodeHeartbeat(5, NmtState::kOperational), F(0x705, {0x05}));
  expectFrame(encodeHeartbeat(127, NmtState::kPreOperational), F(0x77F, {0x7F}));
  expectFrame(encodeHeartbeat(1, NmtState::kStopped), F(0x701, {0x04}));
  auto h = decodeHeartbeat(F(0x703, {0x85}));  // bit 7 = node-guarding toggle
  ASSERT_TRUE(h);
  EXPECT_EQ(h->node, 3);
  EXPECT_EQ(h->state, NmtState::kOperational);
  EXPECT_FALSE(decodeHeartbeat(F(0x703, {})));
  EXPECT_FALSE(decodeHeartbeat(F(0x703, {0x05, 0x00})));
  EXPECT_FALSE(decodeHeartbeat(F(0x703, {0x06})));
  EXPECT_FALSE(decodeHeartbeat(F(0x700, {0x05})));
  EXPECT_FALSE(decodeHeartbeat(F(0x780, {0x05})));
  EXPECT_STREQ(toString(NmtState::kPreOperational), "pre-operational");
}

TEST(Emcy, LayoutAndText) {
  Emcy e;
  e.error_code = 0x8611;
  e.error_register = 0x81;
  e.manufacturer = {1, 2, 3, 4, 5};
  expectFrame(encodeEmcy(3, e), F(0x083, {0x11, 0x86, 0x81, 1, 2, 3, 4, 5}));
  auto d = decodeEmcy(F(0x0FF, {0x10, 0x23, 0x03, 0, 0, 0, 0, 0x09}));
  ASSERT_TRUE(d);
  EXPECT_EQ(d->node, 127);
  EXPECT_EQ(d->emcy.error_code, 0x2310);
  EXPECT_EQ(d->emcy.error_register, 0x03);
  EXPECT_EQ(d->emcy.manufacturer[4], 0x09);
  EXPECT_FALSE(decodeEmcy(F(0x083, {0x11, 0x86, 0x81})));
  EXPECT_FALSE(decodeEmcy(F(0x080, {0, 0, 0, 0, 0, 0, 0, 0})));  // that is SYNC
  EXPECT_EQ(emcyText(0x0000), "error reset or no error");
  EXPECT_EQ(emcyText(0x1000), "generic error");
  EXPECT_EQ(emcyText(0x2310), "continuous over-current");
  EXPECT_EQ(emcyText(0x3210), "DC link over-voltage");
  EXPECT_EQ(emcyText(0x4310), "excess temperature drive");
  EXPECT_NE(emcyText(0x5530).find("EEPROM"), std::string::npos);
  EXPECT_EQ(emcyText(0x7305), "incremental sensor 1 fault");
  EXPECT_EQ(emcyText(0x8611), "following error");
  EXPECT_EQ(emcyText(0x8612), "reference limit");
  EXPECT_EQ(emcyText(0xFF00), "device specific");
  EXPECT_EQ(emcyText(0x2399), "current, device output side (0x2399)");
  EXPECT_EQ(emcyText(0x9001), "external error (0x9001)");
}

TEST(Sdo, ExpeditedDownload) {
  // 0x2B: ccs=1, n=2, e=1, s=1 -> 2 data bytes (controlword 0x000F)
  expectFrame(sdoInitiateDownloadRequest(1, 0x6040, 0x00, {0x0F, 0x00}),
              F(0x601, {0x2B, 0x40, 0x60, 0x00, 0x0F, 0x00, 0x00, 0x00}));
  // 0x23: 4 bytes (target position 100000 = 0x000186A0)
  expectFrame(sdoInitiateDownloadRequest(2, 0x607A, 0x00, {0xA0, 0x86, 0x01, 0x00}),
              F(0x602, {0x23, 0x7A, 0x60, 0x00, 0xA0, 0x86, 0x01, 0x00}));
  // 0x2F: 1 byte (modes of operation = 1)
  expectFrame(sdoInitiateDownloadRequest(3, 0x6060, 0x00, {0x01}),
              F(0x603, {0x2F, 0x60, 0x60, 0x00, 0x01, 0x00, 0x00, 0x00}));
  expectFrame(sdoInitiateDownloadResponse(1, 0x6040, 0x00), F(0x581, {0x60, 0x40, 0x60, 0x00, 0, 0, 0, 0}));

  auto r = decodeSdoRequest(F(0x601, {0x2B, 0x40, 0x60, 0x00, 0x0F, 0x00, 0x00, 0x00}));
  ASSERT_TRUE(r) << r.error();
  EXPECT_EQ(r->command, SdoCommand::kInitiateDownload);
  EXPECT_EQ(r->node, 1);
  EXPECT_EQ(r->index, 0x6040);
  EXPECT_EQ(r->subindex, 0);
  EXPECT_TRUE(r->expedited);
  EXPECT_EQ(r->data, (std::vector<std::uint8_t>{0x0F, 0x00}));
  auto a = decodeSdoResponse(F(0x581, {0x60, 0x40, 0x60, 0x00, 0, 0, 0, 0}));
  ASSERT_TRUE(a);
  EXPECT_EQ(a->command, SdoCommand::kInitiateDownload);
  EXPECT_EQ(a->index, 0x6040);
  // e=1, s=0: "unspecified number of bytes" -> all 4
  auto u = decodeSdoRequest(F(0x601, {0x22, 0x00, 0x20, 0x01, 1, 2, 3, 4}));
  ASSERT_TRUE(u);
  EXPECT_EQ(u->data.size(), 4u);
  EXPECT_EQ(u->subindex, 1);
}

TEST(Sdo, ExpeditedUpload) {
  expectFrame(sdoInitiateUploadRequest(1, 0x6041, 0), F(0x601, {0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0}));
  // 0x4B: scs=2, n=2, e=1, s=1: statusword 0x0237
  expectFrame(sdoInitiateUploadResponse(1, 0x6041, 0, {0x37, 0x02}),
              F(0x581, {0x4B, 0x41, 0x60, 0x00, 0x37, 0x02, 0x00, 0x00}));
  // 0x43: 4 bytes (device type 0x00020192)
  expectFrame(sdoInitiateUploadResponse(9, 0x1000, 0, {0x92, 0x01, 0x02, 0x00}),
              F(0x589, {0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00}));
  auto r = decodeSdoResponse(F(0x581, {0x4F, 0x61, 0x60, 0x00, 0x06, 0xAA, 0xBB, 0xCC}));
  ASSERT_TRUE(r);
  EXPECT_EQ(r->command, SdoCommand::kInitiateUpload);
  EXPECT_TRUE(r->expedited);
  EXPECT_EQ(r->data, (std::vector<std::uint8_t>{0x06}));
  auto q = decodeSdoRequest(F(0x605, {0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}));
  ASSERT_TRUE(q);
  EXPECT_EQ(q->command, SdoCommand::kInitiateUpload);
  EXPECT_EQ(q->node, 5);
  EXPECT_EQ(q->index, 0x1008);
}

TEST(Sdo, SegmentedUpload) {
  // "massage drive" (13 bytes): initiate 0x41 (e=0, s=1) with size, then segments 7 + 6.
  const std::string name = "massage drive";
  const std::vector<std::uint8_t> bytes(name.begin(), name.end());
  expectFrame(sdoInitiateUploadResponse(1, 0x1008, 0, bytes), F(0x581, {0x41, 0x08, 0x10, 0x00, 0x0D, 0, 0, 0}));
  expectFrame(sdoUploadSegmentRequest(1, false), F(0x601, {0x60, 0, 0, 0, 0, 0, 0, 0}));
  expectFrame(sdoUploadSegmentRequest(1, true), F(0x601, {0x70, 0, 0, 0, 0, 0, 0, 0}));
  expectFrame(sdoUploadSegmentResponse(1, false, {'m', 'a', 's', 's', 'a', 'g', 'e'}, false),
              F(0x581, {0x00, 'm', 'a', 's', 's', 'a', 'g', 'e'}));
  // 0x13: t=1, n=1 (7-6), c=1
  expectFrame(sdoUploadSegmentResponse(1, true, {' ', 'd', 'r', 'i', 'v', 'e'}, true),
              F(0x581, {0x13, ' ', 'd', 'r', 'i', 'v', 'e', 0}));
  auto i = decodeSdoResponse(F(0x581, {0x41, 0x08, 0x10, 0x00, 0x0D, 0, 0, 0}));
  ASSERT_TRUE(i);
  EXPECT_FALSE(i->expedited);
  EXPECT_TRUE(i->size_indicated);
  EXPECT_EQ(i->size, 13u);
  auto s = decodeSdoResponse(F(0x581, {0x13, ' ', 'd', 'r', 'i', 'v', 'e', 0}));
  ASSERT_TRUE(s);
  EXPECT_EQ(s->command, SdoCommand::kUploadSegment);
  EXPECT_TRUE(s->toggle);
  EXPECT_TRUE(s->last);
  EXPECT_EQ(s->data.size(), 6u);
  auto q = decodeSdoRequest(F(0x601, {0x70, 0, 0, 0, 0, 0, 0, 0}));
  ASSERT_TRUE(q);
  EXPECT_EQ(q->command, SdoCommand::kUploadSegment);
  EXPECT_TRUE(q->toggle);
}

TEST(Sdo, SegmentedDownload) {
  const std::vector<std::uint8_t> ten = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
  expectFrame(sdoInitiateDownloadRequest(4, 0x2000, 2, ten), F(0x604, {0x21, 0x00, 0x20, 0x02, 0x0A, 0, 0, 0}));
  expectFrame(sdoDownloadSegmentRequest(4, false, {0, 1, 2, 3, 4, 5, 6}, false), F(0x604, {0x00, 0, 1, 2, 3, 4, 5, 6}));
  // 0x19: t=1, n=4, c=1
  expectFrame(sdoDownloadSegmentRequest(4, true, {7, 8, 9}, true), F(0x604, {0x19, 7, 8, 9, 0, 0, 0, 0}));
  expectFrame(sdoDownloadSegmentResponse(4, false), F(0x584, {0x20, 0, 0, 0, 0, 0, 0, 0}));
  expectFrame(sdoDownloadSegmentResponse(4, true), F(0x584, {0x30, 0, 0, 0, 0, 0, 0, 0}));
  auto s = decodeSdoRequest(F(0x604, {0x19, 7, 8, 9, 0, 0, 0, 0}));
  ASSERT_TRUE(s);
  EXPECT_EQ(s->command, SdoCommand::kDownloadSegment);
  EXPECT_EQ(s->data, (std::vector<std::uint8_t>{7, 8, 9}));
  EXPECT_TRUE(s->toggle);
  EXPECT_TRUE(s->last);
  auto r = decodeSdoResponse(F(0x584, {0x30, 0, 0, 0, 0, 0, 0, 0}));
  ASSERT_TRUE(r);
  EXPECT_EQ(r->command, SdoCommand::kDownloadSegment);
  EXPECT_TRUE(r->toggle);
  EXPECT_THROW(sdoDownloadSegmentRequest(4, false, std::vector<std::uint8_t>(8, 0), true), std::invalid_argument);
  EXPECT_THROW(sdoInitiateDownloadRequest(4, 0x2000, 0, {}), std::invalid_argument);
}

TEST(Sdo, AbortLayoutAndTexts) {
  expectFrame(sdoAbortResponse(1, 0x2000, 0, sdo_abort::kNoObject),
              F(0x581, {0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x02, 0x06}));
  expectFrame(sdoAbortRequest(2, 0x6041, 0, sdo_abort::kTimeout),
              F(0x602, {0x80, 0x41, 0x60, 0x00, 0x00, 0x00, 0x04, 0x05}));
  auto a = decodeSdoResponse(F(0x581, {0x80, 0x41, 0x60, 0x00, 0x11, 0x00, 0x09, 0x06}));
  ASSERT_TRUE(a);
  EXPECT_EQ(a->command, SdoCommand::kAbort);
  EXPECT_EQ(a->index, 0x6041);
  EXPECT_EQ(a->abort_code, 0x06090011u);
  EXPECT_EQ(sdoAbortText(0x05040000), "SDO protocol timed out");
  EXPECT_EQ(sdoAbortText(0x06020000), "object does not exist in the object dictionary");
  EXPECT_EQ(sdoAbortText(0x06090011), "sub-index does not exist");
  EXPECT_EQ(sdoAbortText(0x06010002), "attempt to write a read only object");
  EXPECT_EQ(sdoAbortText(0x08000000), "general error");
  EXPECT_EQ(sdoAbortText(0x05040001), "client/server command specifier not valid or unknown");
  EXPECT_EQ(sdoAbortText(0x12345678), "unknown abort code 0x12345678");
}

TEST(Sdo, RejectsMalformedFrames) {
  EXPECT_FALSE(decodeSdoRequest(F(0x601, {0x40, 0x41, 0x60, 0x00})));           // DLC 4
  EXPECT_FALSE(decodeSdoRequest(F(0x600, {0x40, 0x41, 0x60, 0, 0, 0, 0, 0})));  // node 0
  EXPECT_FALSE(decodeSdoRequest(F(0x581, {0x40, 0x41, 0x60, 0, 0, 0, 0, 0})));  // a response id
  EXPECT_FALSE(decodeSdoResponse(F(0x601, {0x60, 0x40, 0x60, 0, 0, 0, 0, 0})));
  auto block = decodeSdoRequest(F(0x601, {0xC0, 0x41, 0x60, 0, 0, 0, 0, 0}));  // ccs 6: block
  ASSERT_FALSE(block);
  EXPECT_NE(block.error().find("block"), std::string::npos);
  auto bad = decodeSdoResponse(F(0x581, {0xE0, 0, 0, 0, 0, 0, 0, 0}));  // scs 7
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("not valid"), std::string::npos);
  can_frame ext = F(0x601 | CAN_EFF_FLAG, {0x40, 0x41, 0x60, 0, 0, 0, 0, 0});
  EXPECT_FALSE(decodeSdoRequest(ext));
  can_frame rtr = F(0x601, {0x40, 0x41, 0x60, 0, 0, 0, 0, 0});
  rtr.can_id |= CAN_RTR_FLAG;
  EXPECT_FALSE(decodeSdoRequest(rtr));
}

TEST(Classify, PredefinedConnectionSet) {
  struct Case {
    canid_t id;
    CobType type;
    int node, pdo;
  };
  for (const Case& c :
       {Case{0x000, CobType::kNmt, 0, 0}, Case{0x080, CobType::kSync, 0, 0}, Case{0x081, CobType::kEmcy, 1, 0},
        Case{0x181, CobType::kTpdo, 1, 1}, Case{0x2FF, CobType::kTpdo, 127, 2}, Case{0x203, CobType::kRpdo, 3, 1},
        Case{0x57F, CobType::kRpdo, 127, 4}, Case{0x585, CobType::kSdoResponse, 5, 0},
        Case{0x605, CobType::kSdoRequest, 5, 0}, Case{0x77F, CobType::kHeartbeat, 127, 0}}) {
    auto r = classify(F(c.id, {}));
    ASSERT_TRUE(r) << std::hex << c.id << " " << r.error();
    EXPECT_EQ(r->type, c.type) << std::hex << c.id;
    EXPECT_EQ(r->node, c.node) << std::hex << c.id;
    EXPECT_EQ(r->pdo, c.pdo) << std::hex << c.id;
  }
  for (canid_t id : {0x100u, 0x7E5u, 0x7E4u, 0x180u, 0x700u, 0x001u})
    EXPECT_FALSE(classify(F(id, {}))) << std::hex << id;
  EXPECT_FALSE(classify(F(0x12345, {})));
}

TEST(Pdo, MappingEntries) {
  EXPECT_EQ(encodeMappingEntry({0x6040, 0, 16}), 0x60400010u);
  EXPECT_EQ(encodeMappingEntry({0x607A, 0, 32}), 0x607A0020u);
  EXPECT_EQ(decodeMappingEntry(0x606C0020), (PdoEntry{0x606C, 0, 32}));
  EXPECT_EQ(decodeMappingEntry(0x20010208), (PdoEntry{0x2001, 2, 8}));
}

TEST(Pdo, PackAndUnpackStatuswordAndPosition) {
  const PdoMapping map = {{0x6041, 0, 16}, {0x6064, 0, 32}};
  auto f = packPdo(0x181, map, {0x0637, static_cast<std::uint32_t>(-1000)});
  ASSERT_TRUE(f) << f.error();
  expectFrame(*f, F(0x181, {0x37, 0x06, 0x18, 0xFC, 0xFF, 0xFF}));
  auto v = unpackPdo(F(0x181, {0x37, 0x06, 0x18, 0xFC, 0xFF, 0xFF}), map);
  ASSERT_TRUE(v) << v.error();
  EXPECT_EQ((*v)[0], 0x0637u);
  EXPECT_EQ(signExtend((*v)[1], 32), -1000);
  EXPECT_FALSE(unpackPdo(F(0x181, {0x37, 0x06, 0x18, 0xFC, 0xFF}), map));              // short
  EXPECT_FALSE(unpackPdo(F(0x181, {0x37, 0x06, 0x18, 0xFC, 0xFF, 0xFF, 0, 0}), map));  // long
  const PdoMapping three = {{0x6041, 0, 16}, {0x6064, 0, 32}, {0x606C, 0, 32}};
  EXPECT_FALSE(packPdo(0x181, three, {1, 2, 3}));  // 80 bits
  EXPECT_FALSE(packPdo(0x181, map, {1}));          // value count
}

TEST(Pdo, BitLevelPacking) {
  const PdoMapping map = {{0x2000, 1, 1}, {0x2000, 2, 7}, {0x2000, 3, 8}, {0x2000, 4, 4}};
  auto f = packPdo(0x201, map, {1, 0x55, 0xA5, 0xF});
  ASSERT_TRUE(f);
  // bit0 = 1, bits1..7 = 0x55 -> byte0 = 0x55 << 1 | 1 = 0xAB; byte1 = 0xA5; byte2 low nibble = 0xF
  expectFrame(*f, F(0x201, {0xAB, 0xA5, 0x0F}));
  auto v = unpackPdo(*f, map);
  ASSERT_TRUE(v);
  EXPECT_EQ(*v, (std::vector<std::uint64_t>{1, 0x55, 0xA5, 0xF}));
  EXPECT_FALSE(mappingBits({{0x2000, 0, 0}}));
}

TEST(Values, BytesAndSignExtension) {
  EXPECT_EQ(toBytes(0x11223344, 4), (std::vector<std::uint8_t>{0x44, 0x33, 0x22, 0x11}));
  EXPECT_EQ(fromBytes({0x44, 0x33, 0x22, 0x11}), 0x11223344u);
  EXPECT_EQ(signExtend(0xFFFF, 16), -1);
  EXPECT_EQ(signExtend(0x7FFF, 16), 32767);
  EXPECT_EQ(signExtend(0x80, 8), -128);
}

TEST(Decoders, RandomFramesNeverThrow) {
  std::mt19937 rng(7);
  int decoded = 0;
  for (int i = 0; i < 200000; ++i) {
    can_frame f{};
    f.can_id = rng() & 0x7FF;
    if (rng() % 50 == 0) f.can_id |= CAN_EFF_FLAG | (rng() & CAN_EFF_MASK);
    if (rng() % 50 == 0) f.can_id |= CAN_RTR_FLAG;
    f.len = static_cast<std::uint8_t>(rng() % 16);
    for (auto& b : f.data) b = static_cast<std::uint8_t>(rng());
    ASSERT_NO_THROW({
      decoded += decodeNmt(f).ok() + decodeSync(f).ok() + decodeHeartbeat(f).ok() + decodeEmcy(f).ok() +
                 decodeSdoRequest(f).ok() + decodeSdoResponse(f).ok() + classify(f).ok() +
                 unpackPdo(f, {{0x6041, 0, 16}, {0x6064, 0, 32}}).ok();
    });
  }
  EXPECT_GT(decoded, 0);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
