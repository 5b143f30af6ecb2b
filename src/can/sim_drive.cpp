// SimDrive (see sim_drive.h): construction, the public API (poll / run,
// power, fault injection, observation) and the advance of simulated time.
// The CiA 301 side is in sim_drive_comm.cpp / sim_drive_sdo.cpp, the CiA 402
// side in sim_drive_motion.cpp.
#include "massage_cell/can/sim_drive.h"

#include <algorithm>
#include <cmath>
#include <thread>

namespace massage_cell::can {

namespace {

constexpr double kStepS = 0.001;  // motion integration step

}  // namespace

SimDrive::SimDrive(Bus& bus, const Clock& clock, const AxisConfig& config)
    : bus_(bus), clock_(clock), config_(config), mechanics_(config.sim.mechanics, config.rated_torque) {
  if (!validNodeId(config_.node_id)) throw std::invalid_argument("SimDrive: node id outside 1..127");
  if (!(config_.counts_per_metre > 0)) throw std::invalid_argument("SimDrive: counts_per_metre must be > 0");
  od_.setWriteHook(
      [this](std::uint16_t i, std::uint8_t s, const std::vector<std::uint8_t>& d) { return checkWrite(i, s, d); });
  actual_ = demand_ = config_.toCounts(config_.sim.start_position);
  physical_m_ = config_.sim.start_position;
  pp_target_ = actual_;
  switch_pos_ = config_.toCounts(config_.sim.home_switch);
  resetApplication();
  resetCommunication();
  last_advance_ = clock_.now();
  applyFilters();
}

void SimDrive::advance(TimePoint now) {
  if (!powered_) {
    last_advance_ = now;
    return;
  }
  double left = std::chrono::duration<double>(now - last_advance_).count();
  consumer_last_ =
      pastOwnStall(consumer_last_, now - last_advance_, now);  // a stall of its own thread: not the master's
  last_advance_ = now;
  left = std::min(left, 10.0);  // after a long stall, do not replay more than 10 s
  while (left > 1e-12) {
    const double dt = std::min(kStepS, left);
    step(dt);
    left -= dt;
  }
}

// --- public -----------------------------------------------------------------------------------------

void SimDrive::poll() {
  std::lock_guard<std::mutex> lock(mutex_);
  const TimePoint now = clock_.now();
  advance(now);
  while (auto f = bus_.receive(Duration::zero())) process(f->frame, now);
  if (!powered_) return;
  sendDueSdoResponses(now);  // delayed SDO responses
  produceHeartbeat(now);     // 0x1017
  checkHeartbeatConsumer(now);
  checkBusRecovery();
  checkChangeTpdos();
}

void SimDrive::run(const std::atomic<bool>& stop, Duration wait) {
  while (!stop) {
    std::optional<TimedFrame> f = bus_.receive(wait);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const TimePoint now = clock_.now();
      advance(now);
      if (f) process(f->frame, now);
    }
    poll();
  }
}

void SimDrive::powerOn() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (powered_) return;
  powered_ = true;
  resetApplication();
  resetCommunication();
  last_advance_ = clock_.now();
  bootUp(clock_.now());
}

void SimDrive::powerOff() {
  std::lock_guard<std::mutex> lock(mutex_);
  powered_ = false;
  resetApplication();  // drops the homing reference
}

void SimDrive::setExternalForce(ExternalForce force) {
  std::lock_guard<std::mutex> lock(mutex_);
  external_ = std::move(force);
}

double SimDrive::externalForce() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return external_force_;
}

double SimDrive::motorForce() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return mechanics_.motorForce();
}

void SimDrive::injectFault(std::uint16_t code, std::array<std::uint8_t, 5> manufacturer) {
  std::lock_guard<std::mutex> lock(mutex_);
  enterFault(code, manufacturer);
}

void SimDrive::setSilent(bool silent) {
  std::lock_guard<std::mutex> lock(mutex_);
  silent_ = silent;
  if (!silent) next_heartbeat_ = clock_.now();
}

void SimDrive::setSdoResponseDelay(Duration delay) {
  std::lock_guard<std::mutex> lock(mutex_);
  sdo_delay_ = delay;
}

void SimDrive::dropSdoResponses(int count) {
  std::lock_guard<std::mutex> lock(mutex_);
  sdo_drop_ = std::max(0, count);
}

void SimDrive::setMotionBlocked(bool blocked) {
  std::lock_guard<std::mutex> lock(mutex_);
  blocked_ = blocked;
}

void SimDrive::failHoming(int attempts, HomingFailure kind) {
  std::lock_guard<std::mutex> lock(mutex_);
  homing_fail_count_ = std::max(0, attempts);
  homing_fail_kind_ = kind;
}

bool SimDrive::powered() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return powered_;
}
NmtState SimDrive::nmtState() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return nmt_;
}
Cia402State SimDrive::state() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return state_;
}
std::uint16_t SimDrive::statusword() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return composeStatusword();
}
std::int32_t SimDrive::position() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<std::int32_t>(std::llround(actual_));
}
double SimDrive::velocity() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return velocity_;
}
std::int8_t SimDrive::modeDisplay() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<std::int8_t>(od_.get(0x6061, 0));
}
bool SimDrive::homed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return homed_;
}
std::uint16_t SimDrive::errorCode() const {
  // Called with or without the lock held by internal code paths: read-only access.
  const ObjectDictionary::Entry* e = od_.find(0x603F, 0);
  return e ? static_cast<std::uint16_t>(fromBytes(e->value)) : 0;
}
std::int64_t SimDrive::object(std::uint16_t index, std::uint8_t sub) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return od_.get(index, sub);
}
SimDrive::Stats SimDrive::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

}  // namespace massage_cell::can
