// The arm on simulated drives (see sim_cell.h).
#include "massage_cell/arm/sim_cell.h"

#include <pthread.h>
#include <sched.h>

#include <cstring>

namespace massage_cell::arm {

std::string useRealtimeScheduling(int priority) {
  if (priority < 1 || priority > 99) return "priority must be 1..99, got " + std::to_string(priority);
  sched_param param{};
  param.sched_priority = priority;
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
  return rc == 0 ? std::string() : std::string(std::strerror(rc));
}

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

void SimCell::start() {
  if (running_) return;
  running_ = true;
  stop_ = false;
  for (auto& d : drives_) d->powerOn();
  for (auto& d : drives_) {
    can::SimDrive* drive = d.get();
    threads_.emplace_back([this, drive] { drive->run(stop_, std::chrono::milliseconds(1)); });
  }
  controller_->master().start();
  controller_->start();
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
