// The arm on simulated drives, in-process and on the real clock: a
// VirtualBus, one SimDrive per configured CAN axis (each polled in its own
// thread), the Controller's master in its own thread. What the arm node runs
// with can_interface "sim" and what arm_bench measures, with the same
// real-time options (can/realtime.h).
#pragma once

#include <atomic>
#include <memory>
#include <thread>
#include <vector>

#include "massage_cell/arm/controller.h"
#include "massage_cell/arm/sim_body.h"
#include "massage_cell/can/sim_drive.h"
#include "massage_cell/can/virtual_bus.h"

namespace massage_cell::arm {

/// The simulator's fault hook text "<axis> <EMCY code>" ("Y 0x2310"): the axis index (0..2) of a name in
/// `config`.axis_names and the code (1..0xFFFF, decimal or 0x-hex); false for anything else.
bool parseFaultInjection(const ArmConfig& config, const std::string& text, int* axis, std::uint16_t* code);

class SimCell {
 public:
  explicit SimCell(ArmConfig config);
  ~SimCell();
  SimCell(const SimCell&) = delete;
  SimCell& operator=(const SimCell&) = delete;

  /// Powers the drives, starts the threads and the controller's bring-up.
  /// The master's thread starts through Controller::startThread(realtime)
  /// (as on real drives); with realtime.priority > 0 the drives' threads,
  /// the simulated hardware, get the same SCHED_FIFO priority. Returns what
  /// the threads got (a refusal: normal scheduling, the reason and the fix).
  can::RealtimeStatus start(const can::RealtimeOptions& realtime = {});
  /// Stops the threads (the destructor does too).
  void stop();

  Controller& controller() { return *controller_; }
  can::VirtualBus& bus() { return bus_; }
  /// The simulated drive of arm joint i (0 = x, 1 = y, 2 = z).
  can::SimDrive& drive(int i) { return *drives_.at(static_cast<std::size_t>(joint_drive_[i])); }
  /// Puts `body` under the tool (nullptr: none): the Z drive feels its force (SimBody::force at the tool tip of the
  /// drives' physical positions, breathing on the steady clock from the cell's construction).
  void setBody(std::shared_ptr<const SimBody> body);
  /// Puts a back known by points under the tool (SkinPoints within `radius` of each; the default tissue; the points
  /// carry the breathing) and returns the points to update.
  std::shared_ptr<SkinPoints> setSkin(double radius);
  /// The true force the body pushes the tool up with now, N (0 without a body).
  double bodyForce() { return drive(2).externalForce(); }
  /// Seconds on the body's clock (its breathing phase).
  double bodyTime() const;
  /// The endpoint the master uses (fault injection: VirtualBus::setBusOff).
  can::VirtualBus::Endpoint& masterEndpoint() { return *master_ep_; }

 private:
  can::VirtualBus bus_;
  std::shared_ptr<can::VirtualBus::Endpoint> master_ep_;
  std::vector<std::shared_ptr<can::VirtualBus::Endpoint>> drive_eps_;
  std::vector<std::unique_ptr<can::SimDrive>> drives_;
  std::array<int, 3> joint_drive_{};
  std::unique_ptr<Controller> controller_;
  std::atomic<bool> stop_{false};
  std::vector<std::thread> threads_;
  bool running_ = false;
  can::RealtimeStatus status_;
  can::TimePoint epoch_;
};

}  // namespace massage_cell::arm
