// Fuzz target: the CANopen master, its SDO client and the CiA 402 axes with a
// stranger on the bus. Two simulated drives are brought up on a VirtualBus
// (VirtualClock) while the input interleaves arbitrary frames — ids near
// every service's COB-IDs, any DLC and payload — with time steps and axis
// commands (enable, home, move, quick stop, fault reset). Whatever arrives,
// the master must keep going: no crash, no exception, and every malformed
// frame reported as an event with its reason.
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <memory>
#include <vector>

#include "fuzz_input.h"
#include "massage_cell/can/cia402.h"
#include "massage_cell/can/master.h"
#include "massage_cell/can/sim_drive.h"
#include "massage_cell/can/virtual_bus.h"

using namespace massage_cell::can;
using namespace std::chrono_literals;

namespace {

AxisConfig axis(const char* name, std::uint8_t id) {
  AxisConfig a;
  a.name = name;
  a.node_id = id;
  a.counts_per_metre = 100000;
  a.heartbeat_ms = 20;
  a.heartbeat_timeout_ms = 60;
  a.homing_timeout_ms = 500;
  return a;
}

can_frame strangeFrame(massage_cell::fuzz::FuzzInput& in) {
  static const canid_t kBases[] = {0x000, 0x080, 0x100, 0x180, 0x200, 0x280, 0x300, 0x380,
                                   0x400, 0x480, 0x500, 0x580, 0x600, 0x700, 0x780};
  can_frame f{};
  const std::uint8_t how = in.byte();
  if (how % 8 == 0) {
    f.can_id = in.bits<std::uint32_t>();  // anything: extended, RTR, error frames
  } else {
    f.can_id = kBases[how % 15] + in.byte() % 4;  // near our nodes 1 and 2 (and 0, 3)
  }
  f.can_dlc = in.byte() % 10;
  const std::uint64_t payload = in.bits<std::uint64_t>();
  std::memcpy(f.data, &payload, sizeof(payload));
  return f;
}

void command(Cia402Axis& a, std::uint8_t what, massage_cell::fuzz::FuzzInput& in) {
  switch (what % 6) {
    case 0:
      a.enable();
      break;
    case 1:
      a.home();
      break;
    case 2:
      a.moveTo(in.real(-2.0, 2.0, true));
      break;
    case 3:
      a.quickStop();
      break;
    case 4:
      a.faultReset();
      break;
    default:
      a.disable();
      break;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  massage_cell::fuzz::FuzzInput in(data, size);
  VirtualClock clock;
  VirtualBus bus(clock);
  CanConfig config;
  config.axes = {axis("X", 1), axis("Y", 2)};
  auto master_ep = bus.open("master");
  auto stranger = bus.open("stranger");
  std::vector<std::shared_ptr<VirtualBus::Endpoint>> drive_eps;
  std::vector<std::unique_ptr<SimDrive>> drives;
  for (const AxisConfig& a : config.axes) {
    drive_eps.push_back(bus.open(a.name));
    drives.push_back(std::make_unique<SimDrive>(*drive_eps.back(), clock, a));
    drives.back()->powerOn();
  }
  Master master(*master_ep, clock, config);
  std::vector<std::unique_ptr<Cia402Axis>> axes;
  for (const AxisConfig& a : config.axes) axes.push_back(std::make_unique<Cia402Axis>(master, a));
  master.bringUp();

  std::uint64_t malformed = 0;
  auto step = [&](Duration dt) {
    clock.advance(dt);
    for (auto& d : drives) d->poll();
    master.poll();
    for (const Event& e : master.takeEvents()) {
      if (e.type == EventType::kMalformedFrame) {
        ++malformed;
        if (e.text.empty()) {
          std::cerr << "fuzz_can_master: a malformed-frame event without a reason\n";
          std::abort();
        }
      }
    }
  };
  for (int i = 0; i < 200; ++i) step(1ms);  // most inputs start against drives that are up
  for (int ops = 0; in.remaining() > 0 && ops < 400; ++ops) {
    const std::uint8_t op = in.byte();
    if (op < 160) {
      stranger->send(strangeFrame(in));
      step(std::chrono::microseconds(100));
    } else if (op < 230) {
      step(std::chrono::milliseconds(1 + in.byte() % 50));
    } else if (op < 250) {
      command(*axes[op % 2], in.byte(), in);
    } else {
      master.bringUp(static_cast<std::uint8_t>(1 + op % 2));
    }
  }
  for (int i = 0; i < 50; ++i) step(2ms);
  (void)master.stats();
  for (const AxisConfig& a : config.axes) (void)master.feedback(a.node_id);
  return 0;
}
