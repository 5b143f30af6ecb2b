// The arm controller's test rig (test_controller.cpp, test_force_fuzz.cpp): three simulated CiA 402 drives on a
// VirtualBus, on a VirtualClock (each step = 1 ms: the drives poll, then the master and with it the controller's
// cycle, once per SYNC); a sniffer endpoint records every RPDO1 (controlword + target) the master sends; backs of
// simulated tissue under the Z drive, and the requests that press them by force.
#pragma once

#include <Eigen/Geometry>

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "massage_cell/arm/controller.h"
#include "massage_cell/arm/sim_body.h"
#include "massage_cell/can/sim_drive.h"
#include "massage_cell/can/virtual_bus.h"

#ifndef MASSAGE_CELL_SOURCE_DIR
#define MASSAGE_CELL_SOURCE_DIR "."
#endif

namespace massage_cell::arm::rig {

using namespace std::chrono_literals;

inline ArmConfig exampleConfig() { return loadArmConfig(std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/arm.yaml"); }

struct Rpdo {
  can::TimePoint stamp;
  std::uint8_t node;
  std::uint16_t controlword;
  std::int32_t target;
};

struct Rig {
  explicit Rig(ArmConfig c = exampleConfig()) : config(std::move(c)) {
    for (const can::AxisConfig& a : config.can.axes) {
      eps.push_back(bus.open("drive " + a.name));
      drives.push_back(std::make_unique<can::SimDrive>(*eps.back(), clock, a));
    }
    controller = std::make_unique<Controller>(*master_ep, clock, config);
    controller->setLog([this](const std::string& s) { log += s + "\n"; });
  }
  void step() {
    clock.advance(1ms);
    for (auto& d : drives) d->poll();
    controller->master().poll();
    while (auto f = sniffer->receive(can::Duration::zero())) {
      const canid_t id = f->frame.can_id;
      if (id > 0x200 && id < 0x280 && f->frame.can_dlc == 6) {
        const auto* b = f->frame.data;
        rpdos.push_back(
            {f->stamp, static_cast<std::uint8_t>(id - 0x200), static_cast<std::uint16_t>(b[0] | b[1] << 8),
             static_cast<std::int32_t>(b[2] | b[3] << 8 | b[4] << 16 | static_cast<std::uint32_t>(b[5]) << 24)});
      }
    }
    if (keep_alive) controller->keepAlive();
    if (observer) observer();
  }
  bool runUntil(const std::function<bool()>& pred, can::Duration limit) {
    for (can::Duration t{}; t < limit; t += 1ms) {
      if (pred()) return true;
      step();
    }
    return pred();
  }
  void run(can::Duration d) {
    runUntil([] { return false; }, d);
  }
  bool start() {
    for (auto& d : drives) d->powerOn();
    step();
    controller->start();
    return runUntil([&] { return controller->mode() != Mode::kStarting; }, 5s) && controller->mode() == Mode::kReady;
  }
  /// Runs until the command is done; true when it succeeded.
  bool finish(const Accepted& a, can::Duration limit = 60s) {
    if (!a) return false;
    runUntil([&] { return controller->result(a.id).done; }, limit);
    return controller->result(a.id).success;
  }
  std::string message(const Accepted& a) const { return a ? controller->result(a.id).message : a.error; }
  bool home() { return finish(controller->home()); }
  Eigen::Vector3d drivePositions() const {
    Eigen::Vector3d q;
    for (int i = 0; i < 3; ++i) q[i] = config.axis(i).toMetres(drives[i]->position());
    return q;
  }
  Eigen::Vector3d tool() const { return config.toolOf(drivePositions()); }
  bool allStill() const {
    for (const auto& d : drives)
      if (d->velocity() != 0.0) return false;
    return true;
  }

  can::VirtualClock clock;
  can::VirtualBus bus{clock};
  std::shared_ptr<can::VirtualBus::Endpoint> master_ep = bus.open("master");
  std::shared_ptr<can::VirtualBus::Endpoint> sniffer = bus.open("sniffer");
  ArmConfig config;
  std::vector<std::shared_ptr<can::VirtualBus::Endpoint>> eps;
  std::vector<std::unique_ptr<can::SimDrive>> drives;
  std::unique_ptr<Controller> controller;
  std::vector<Rpdo> rpdos;
  bool keep_alive = true;
  std::function<void()> observer;
  std::string log;
};

inline bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

/// `body` under the rig's tool: the Z drive feels it where the X and Y drives stand, on the rig's clock.
inline void putBody(Rig& r, std::shared_ptr<const SimBody> body) {
  const can::SimDrive* x = r.drives[0].get();
  const can::SimDrive* y = r.drives[1].get();
  const can::VirtualClock* clock = &r.clock;
  r.drives[2]->setExternalForce([=](double z, double vz) {
    const double t = std::chrono::duration<double>(clock->now().time_since_epoch()).count();
    return body->force(Eigen::Vector3d(x->physicalPosition(), y->physicalPosition(), z), vz, t);
  });
}

/// The rig with a flat back 15 cm above the table under the Z drive (breathing 3 mm p-p / 4 s unless `still`).
inline void putBack(Rig& r, double skin_z, bool still = false) {
  Breathing b;
  if (still) b.amplitude = 0.0;
  const auto body = std::make_shared<SimBody>(SimBody::flat(skin_z, Tissue{}, b));
  putBody(r, body);
}

inline PressRequest byForce(double force, double hold) {
  PressRequest request;
  request.targets.push_back({"BL23_L", "lower_back", Eigen::Vector3d(0.3, 0.2, 0.15), Eigen::Vector3d::UnitZ()});
  request.mode = PressConfig::Mode::kForce;
  request.force = force;
  request.hold = hold;
  return request;
}

/// A back rising 2 cm over a stroke's 16 cm along x (breathing unless `still`) under the rig's tool.
inline double slopedSkin(double x) { return 0.15 + 0.125 * (x - 0.25); }

inline void putSlopedBack(Rig& r, bool still = false) {
  Breathing b;
  if (still) b.amplitude = 0.0;
  const auto body = std::make_shared<SimBody>([](double x, double) { return slopedSkin(x); },
                                              [](double, double) { return Tissue{}; }, b);
  putBody(r, body);
}

/// A stroke at 20 N from x 0.25 to 0.41 m over the sloped back, its points where vision put them (+-2 mm).
inline PressRequest strokeRequest() {
  PressRequest request;
  request.technique = Technique::kStroke;
  request.mode = PressConfig::Mode::kForce;
  request.force = 20.0;
  const double vision_error[] = {0.002, -0.002, 0.001, -0.001, 0.002};
  for (int i = 0; i < 5; ++i) {
    const double x = 0.25 + 0.04 * i;
    request.targets.push_back({"BL" + std::to_string(11 + 2 * i) + "_L", "upper_back",
                               Eigen::Vector3d(x, 0.2 + 0.005 * (i % 2), slopedSkin(x) + vision_error[i]),
                               Eigen::Vector3d::UnitZ()});
  }
  return request;
}

}  // namespace massage_cell::arm::rig
