// The arm on simulated drives (see sim_cell.h).
#include "massage_cell/arm/sim_cell.h"

namespace massage_cell::arm {

SimCell::SimCell(ArmConfig config) : bus_(can::SteadyClock::instance()) {
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

}  // namespace massage_cell::arm
