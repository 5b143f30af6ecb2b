// The arm on simulated drives (see sim_cell.h).
#include "massage_cell/arm/sim_cell.h"

#include <sstream>
#include <string>

namespace massage_cell::arm {

SimCell::SimCell(ArmConfig config) : bus_(can::SteadyClock::instance()), epoch_(can::SteadyClock::instance().now()) {
  master_ep_ = bus_.open("master");
  for (const can::AxisConfig& a : config.can.axes) {
    drive_eps_.push_back(bus_.open("drive " + a.name));
    drives_.push_back(std::make_unique<can::SimDrive>(*drive_eps_.back(), can::SteadyClock::instance(), a));
  }
  for (int i = 0; i < 3; ++i) {
    for (std::size_t d = 0; d < config.can.axes.size(); ++d) {
      if (config.can.axes[d].name == config.axis_names[i]) joint_drive_[i] = static_cast<int>(d);
    }
  }
  controller_ = std::make_unique<Controller>(*master_ep_, can::SteadyClock::instance(), std::move(config));
}

SimCell::~SimCell() { stop(); }

double SimCell::bodyTime() const {
  return std::chrono::duration<double>(can::SteadyClock::instance().now() - epoch_).count();
}

std::shared_ptr<SkinPoints> SimCell::setSkin(double radius) {
  auto skin = std::make_shared<SkinPoints>(radius);
  Breathing carried;  // the points breathe already
  carried.amplitude = 0.0;
  setBody(std::make_shared<SimBody>(
      SkinPoints::surface(skin), [](double, double) { return Tissue{}; }, carried));
  return skin;
}

void SimCell::setBody(std::shared_ptr<const SimBody> body) {
  if (!body) {
    drive(2).setExternalForce({});
    return;
  }
  can::SimDrive* x = &drive(0);
  can::SimDrive* y = &drive(1);
  const Eigen::Vector3d offset = controller_->config().tool_offset;
  drive(2).setExternalForce([this, x, y, offset, body](double z, double vz) {
    const Eigen::Vector3d tool = Eigen::Vector3d(x->physicalPosition(), y->physicalPosition(), z) + offset;
    return body->force(tool, vz, bodyTime());
  });
}

can::RealtimeStatus SimCell::start(const can::RealtimeOptions& realtime) {
  if (running_) return status_;
  running_ = true;
  stop_ = false;
  for (auto& d : drives_) d->powerOn();
  for (auto& d : drives_) {
    can::SimDrive* drive = d.get();
    threads_.emplace_back([this, drive] { drive->run(stop_, std::chrono::milliseconds(1)); });
  }
  status_ = controller_->startThread(realtime);
  if (status_.active()) {
    for (auto& t : threads_) {
      const std::string error = can::setRealtimePriority(t.native_handle(), realtime.priority);
      if (!error.empty()) status_.error += (status_.error.empty() ? "" : "; ") + ("simulated drive thread: " + error);
    }
  }
  controller_->start();
  return status_;
}

void SimCell::stop() {
  if (!running_) return;
  running_ = false;
  controller_->master().stop();
  stop_ = true;
  for (auto& t : threads_) t.join();
  threads_.clear();
}

bool parseFaultInjection(const ArmConfig& config, const std::string& text, int* axis, std::uint16_t* code) {
  std::istringstream in(text);
  std::string name, code_text, rest;
  if (!(in >> name >> code_text) || (in >> rest)) return false;
  *axis = -1;
  for (int i = 0; i < 3; ++i) {
    if (config.axis_names[i] == name) *axis = i;
  }
  std::size_t used = 0;
  unsigned long value = 0;
  try {
    value = std::stoul(code_text, &used, 0);
  } catch (const std::exception&) {
    return false;
  }
  if (*axis < 0 || used != code_text.size() || value == 0 || value > 0xFFFF) return false;
  *code = static_cast<std::uint16_t>(value);
  return true;
}

}  // namespace massage_cell::arm
