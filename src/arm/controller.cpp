// The arm controller (see controller.h).
#include "massage_cell/arm/controller.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "massage_cell/can/canopen.h"

namespace massage_cell::arm {

namespace {

using can::Cia402State;
using Lock = std::lock_guard<can::RecursivePiMutex>;

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

bool faulted(Cia402State s) { return s == Cia402State::kFault || s == Cia402State::kFaultReactionActive; }

std::string axisLabel(const can::AxisConfig& a) {
  return "axis " + a.name + " (node " + std::to_string(a.node_id) + ")";
}

}  // namespace

const char* toString(Mode mode) {
  switch (mode) {
    case Mode::kStarting:
      return "starting";
    case Mode::kReady:
      return "ready (not homed)";
    case Mode::kHoming:
      return "homing";
    case Mode::kIdle:
      return "idle";
    case Mode::kMoving:
      return "moving";
    case Mode::kMassaging:
      return "massaging";
    case Mode::kStopping:
      return "stopping";
    case Mode::kResetting:
      return "resetting";
    case Mode::kFault:
      return "fault";
    case Mode::kEstop:
      return "e-stop";
    case Mode::kReleasing:
      return "e-stop (releasing the pressure)";
  }
  return "?";
}

// --- set-up ------------------------------------------------------------------------------------------

Controller::Controller(can::Bus& bus, const can::Clock& clock, ArmConfig config)
    : config_(std::move(config)), clock_(clock), bus_(bus) {
  validate(config_);
  tool_force_ = std::make_unique<ToolForce>(config_);
  master_ = std::make_unique<can::Master>(bus_, clock_, config_.can);
  for (int i = 0; i < 3; ++i) axes_[i] = std::make_unique<can::Cia402Axis>(*master_, config_.axis(i));
  listener_id_ = master_->addEventListener([this](const can::Event& e) { events_.push_back(e); });
  master_->setBeforeSyncHook([this](can::TimePoint now) { cycle(now); });
}

Controller::~Controller() {
  master_->stop();  // no cycle may run on a half-destroyed controller
  Lock lock(master_->mutex());
  master_->setBeforeSyncHook({});
  master_->removeEventListener(listener_id_);
}

can::RealtimeStatus Controller::startThread(const can::RealtimeOptions& options) {
  can::RealtimeStatus s;
  s.requested = options.priority;
  s.lock_requested = options.lock_memory;
  auto note = [&s](const std::string& error) {
    if (!error.empty()) s.error += (s.error.empty() ? "" : "; ") + error;
  };
  if (options.lock_memory) {
    const std::string error = can::lockMemory();
    s.memory_locked = error.empty();
    note(error);
  }
  note(master_->start(options.priority));
  s.priority = master_->threadPriority();
  return s;
}

void Controller::start() {
  Lock lock(master_->mutex());
  started_ = true;
  start_time_ = clock_.now();
  mode_ = Mode::kStarting;
  master_->bringUp();
  log("bringing up the CAN nodes");
}

void Controller::setLog(Log log) {
  Lock lock(master_->mutex());
  log_ = std::move(log);
}

void Controller::setCycleObserver(CycleObserver observer) {
  Lock lock(master_->mutex());
  cycle_observer_ = std::move(observer);
}

void Controller::log(const std::string& text) {
  if (log_) log_(text);
}

Eigen::Vector3d Controller::joints() const {
  Eigen::Vector3d q;
  for (int i = 0; i < 3; ++i) q[i] = axes_[i]->position();
  return q;
}

bool Controller::allHomed() const { return axes_[0]->homed() && axes_[1]->homed() && axes_[2]->homed(); }

// --- the cycle ---------------------------------------------------------------------------------------

void Controller::cycle(can::TimePoint now) {
  // The master's before-SYNC hook: once per SYNC, just before that SYNC's
  // RPDOs (after the axes' tick handlers of the same poll).
  ++cycles_;
  if (cycle_observer_) cycle_observer_(now);
  if (!started_) return;
  handleEvents();
  senseForce(now);
  if (mode_ == Mode::kStarting) {
    bool up = true;
    std::string missing;
    for (int i = 0; i < 3; ++i) {
      const can::AxisConfig& a = config_.axis(i);
      const can::NodeState ns = master_->nodeState(a.node_id);
      if (ns != can::NodeState::kOperational || !axes_[i]->valid()) {
        up = false;
        if (missing.empty()) missing = axisLabel(a) + " is " + can::toString(ns);
      }
    }
    if (up) {
      mode_ = allHomed() ? Mode::kIdle : Mode::kReady;
      log("CAN nodes operational; " + std::string(toString(mode_)));
    } else if (now - start_time_ >
               std::chrono::duration_cast<can::Duration>(std::chrono::duration<double>(config_.bringup_timeout))) {
      fault("bring-up did not finish within " + fmt("%.1f", config_.bringup_timeout) + " s: " + missing);
    }
    if (mode_ == Mode::kStarting) return;
  }
  checkFaults();
  if (mode_ == Mode::kFault || mode_ == Mode::kEstop) {
    quickStopAll();  // also drives that come back (heartbeat resumed, bus recovered) still enabled
    return;
  }
  // Command watchdog.
  if ((mode_ == Mode::kMoving || mode_ == Mode::kMassaging) && config_.watchdog_timeout > 0.0 && !aborting_) {
    const double since = std::chrono::duration<double>(now - last_keepalive_).count();
    if (since > config_.watchdog_timeout) {
      const std::string why = "command watchdog: no keep-alive for " + fmt("%.2f", since) + " s (limit " +
                              fmt("%.2f", config_.watchdog_timeout) + " s)";
      log(why);
      if (mode_ == Mode::kMassaging && current_ && current_->kind == Action::Kind::kStep && current_->step.contact) {
        retract(why);
      } else {
        stopAndReenable(why);
      }
    }
  }
  if (mode_ == Mode::kMassaging) guardForce();
  runQueue(now);
}

void Controller::handleEvents() {
  // Our listener's copy of every master event: a takeEvents() reader elsewhere takes nothing from us.
  std::vector<can::Event> events;
  events.swap(events_);
  for (const can::Event& e : events) {
    log(std::string(can::toString(e.type)) + ": " + e.text);
    switch (e.type) {
      case can::EventType::kHeartbeatTimeout:
      case can::EventType::kConfigureFailed:
        fault(e.text);
        break;
      case can::EventType::kEmcy:
        if (e.emcy_code != 0) fault(e.text);
        break;
      case can::EventType::kBusStateChanged:
        if (e.text.find("-> bus-off") != std::string::npos || e.text.find("-> down") != std::string::npos) {
          fault("CAN bus " + e.text);
        }
        break;
      default:
        break;
    }
  }
}

void Controller::checkFaults() {
  for (int i = 0; i < 3; ++i) {
    const can::AxisConfig& a = config_.axis(i);
    const can::NodeState ns = master_->nodeState(a.node_id);
    if (ns != can::NodeState::kOperational) {
      fault(axisLabel(a) + ": node is " + can::toString(ns));
      continue;
    }
    if (mode_ == Mode::kResetting) continue;  // the reset itself clears drive faults
    if (axes_[i]->valid() && faulted(axes_[i]->state())) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "0x%04X", axes_[i]->statusword());
      std::string text = axisLabel(a) + ": drive in '" + can::toString(axes_[i]->state()) + "' (statusword " + buf;
      const can::DriveFeedback fb = master_->feedback(a.node_id);
      if (fb.emcy_code != 0) {
        std::snprintf(buf, sizeof buf, "0x%04X", fb.emcy_code);
        text += ", last EMCY " + std::string(buf) + " " + can::emcyText(fb.emcy_code);
      }
      fault(text + ")");
    }
  }
  const can::BusState bs = bus_.status().state;
  bus_state_ = bs;
  if (bs == can::BusState::kBusOff || bs == can::BusState::kDown) {
    fault("CAN bus " + bus_.name() + " is " + can::toString(bs));
  }
}

void Controller::fault(const std::string& why) {
  if (std::find(faults_.begin(), faults_.end(), why) == faults_.end()) {
    faults_.push_back(why);
    log("FAULT: " + why);
  }
  if (mode_ == Mode::kFault || mode_ == Mode::kEstop) return;
  last_error_ = why;
  finish(false, "aborted by a fault: " + why);
  queue_.clear();
  current_.reset();
  aborting_ = false;
  for (auto& w : written_profile_) w.reset();
  quickStopAll();
  mode_ = Mode::kFault;
}

void Controller::quickStopAll() {
  for (int i = 0; i < 3; ++i) {
    if (!axes_[i]->valid() || axes_[i]->state() != Cia402State::kOperationEnabled) continue;
    if (axes_[i]->busy() && axes_[i]->operation() == can::Cia402Axis::Operation::kQuickStop) continue;
    axes_[i]->quickStop();
  }
}

void Controller::runQueue(can::TimePoint now) {
  for (int guard = 0; guard < 1000; ++guard) {
    if (!current_) {
      if (queue_.empty()) {
        const auto it = results_.find(command_);
        if (it != results_.end() && !it->second.done) {
          std::string message;
          bool ok = !aborting_;
          if (aborting_) {
            message = abort_reason_;
            if (mode_ == Mode::kMassaging) message += "; tool retracted to " + formatPoint(config_.toolOf(joints()));
          } else if (command_what_ == "home") {
            message = "homed; tool at " + formatPoint(config_.toolOf(joints()));
          } else if (command_what_ == "move") {
            message = "moved; tool at " + formatPoint(config_.toolOf(joints()));
          } else if (command_what_ == "massage") {
            message = "massage done: " + std::to_string(presses_done_) + " press" + (presses_done_ == 1 ? "" : "es");
          } else if (command_what_ == "reset") {
            message = "faults cleared, drives enabled";
          } else {
            message = command_what_ + " done";
          }
          finish(ok, message);
        }
        aborting_ = false;
        if (mode_ == Mode::kReleasing) {  // backed off: stopped and latched, as any e-stop
          quickStopAll();
          mode_ = Mode::kEstop;
          log("E-STOP: pressure released, tool at " + formatPoint(config_.toolOf(joints())) +
              "; latched until reset_fault");
          return;
        }
        mode_ = allHomed() ? Mode::kIdle : Mode::kReady;
        return;
      }
      current_ = queue_.front();
      queue_.pop_front();
      phase_ = Phase::kStart;
      action_start_ = now;
      if (!startAction(*current_, now)) return;
    }
    if (!tickAction(*current_, now)) return;
    if (current_ && current_->kind == Action::Kind::kStep && current_->step.press_done) ++presses_done_;
    if (current_ && current_->kind == Action::Kind::kStep && current_->step.force_calibration &&
        (queue_.empty() || !queue_.front().step.force_calibration))
      finishForceCalibration();
    current_.reset();
  }
}

bool Controller::startAction(Action& a, can::TimePoint) {
  started_axes_ = 0;
  switch (a.kind) {
    case Action::Kind::kEnableAll:
      for (int i = 0; i < 3; ++i) {
        if (axes_[i]->state() != Cia402State::kOperationEnabled || axes_[i]->busy()) {
          axes_[i]->enable();
          started_axes_ |= 1u << i;
        }
      }
      return true;
    case Action::Kind::kQuickStopAll:
      for (int i = 0; i < 3; ++i) {
        if (axes_[i]->state() == Cia402State::kOperationEnabled) {
          axes_[i]->quickStop();
          started_axes_ |= 1u << i;
        }
      }
      return true;
    case Action::Kind::kWaitStopped:  // the operations running (an e-stop's quick stops) to end
      for (int i = 0; i < 3; ++i) {
        if (axes_[i]->busy()) started_axes_ |= 1u << i;
      }
      return true;
    case Action::Kind::kFaultResetAll:
      for (int i = 0; i < 3; ++i) {
        if (faulted(axes_[i]->state())) {
          axes_[i]->faultReset();
          started_axes_ |= 1u << i;
        }
      }
      return true;
    case Action::Kind::kHome:
      for (int i = 0; i < 3; ++i) {
        if (a.mask & (1u << i)) {
          axes_[i]->home();
          started_axes_ |= 1u << i;
          log(axisLabel(config_.axis(i)) + ": homing");
        }
      }
      return true;
    case Action::Kind::kStep:
      if (!a.step.label.empty()) log(a.step.label);
      if (a.step.force_calibration && !calibrating_force_) tool_force_->startCalibration();
      calibrating_force_ = a.step.force_calibration;
      // Leaving the approach point into contact: the tool is still and touches nothing, the force's zero is here.
      if (a.step.contact && !in_contact_) tool_force_->rezero();
      in_contact_ = a.step.contact;
      if (a.step.kind == Step::Kind::kMove) startMove(a.step);
      if (a.step.kind == Step::Kind::kForcePress) startForcePress(a.step);
      return mode_ != Mode::kFault;
    case Action::Kind::kProfileMode:
      for (int i = 0; i < 3; ++i) {
        if (axes_[i]->mode() == can::Mode::kCyclicSyncPosition) {
          axes_[i]->setModeOfOperation(can::Mode::kProfilePosition);
          started_axes_ |= 1u << i;
        }
      }
      return true;
  }
  return true;
}

bool Controller::waitOps(const std::string& what) {
  for (int i = 0; i < 3; ++i) {
    if (!(started_axes_ & (1u << i))) continue;
    const can::Cia402Axis::Status s = axes_[i]->status();
    if (s == can::Cia402Axis::Status::kRunning) return false;
    if (s == can::Cia402Axis::Status::kFailed) {
      fault(what + " failed: " + axes_[i]->error());
      return false;
    }
  }
  return true;
}

bool Controller::tickAction(Action& a, can::TimePoint now) {
  switch (a.kind) {
    case Action::Kind::kEnableAll:
      return waitOps("enable");
    case Action::Kind::kQuickStopAll:
      return waitOps("quick stop");
    case Action::Kind::kWaitStopped:
      return waitOps("quick stop");
    case Action::Kind::kFaultResetAll:
      return waitOps("fault reset");
    case Action::Kind::kHome:
      return waitOps("homing");
    case Action::Kind::kProfileMode:
      return waitOps("back to profile position");
    case Action::Kind::kStep:
      break;
  }
  const Step& s = a.step;
  if (s.kind == Step::Kind::kHold) return std::chrono::duration<double>(now - action_start_).count() >= s.duration;
  if (s.kind == Step::Kind::kForcePress) return tickForcePress(s);
  if (phase_ == Phase::kProfiles) {
    if (sdo_pending_ > 0) return false;
    if (!sdo_error_.empty()) {
      fault("SDO write of the move profile failed: " + sdo_error_);
      return false;
    }
    for (int i = 0; i < 3; ++i) {
      if (started_axes_ & (1u << i)) axes_[i]->moveToCounts(goal_counts_[i]);
    }
    phase_ = Phase::kRunning;
    return false;
  }
  if (!waitOps("move")) return false;
  const Eigen::Vector3d q = joints();
  const Eigen::Vector3d goal = config_.jointsOf(s.tool);
  const double error = (q - goal).norm();
  if (error > config_.position_tolerance) {
    fault("move ended " + fmt("%.3f", error * 1000.0) + " mm from its goal " + formatPoint(s.tool) + " (tolerance " +
          fmt("%.3f", config_.position_tolerance * 1000.0) + " mm)");
    return false;
  }
  return true;
}

void Controller::startMove(const Step& s) {
  // Defensive: plans are checked when accepted; a goal outside the limits never reaches a drive.
  if (std::string bad = checkTool(config_, s.tool); !bad.empty()) {
    fault("internal: refusing a move goal: " + bad);
    return;
  }
  const Eigen::Vector3d q0 = joints();
  const Eigen::Vector3d q = config_.jointsOf(s.tool);
  Eigen::Vector3d vmax, amax;
  for (int i = 0; i < 3; ++i) {
    vmax[i] = config_.joints[i].max_velocity;
    amax[i] = config_.joints[i].max_acceleration;
  }
  profile_ = planSyncProfile(q0, q, vmax, amax, s.speed, s.accel);
  started_axes_ = 0;
  sdo_pending_ = 0;
  sdo_error_.clear();
  const unsigned gen = ++sdo_generation_;
  for (int i = 0; i < 3; ++i) {
    const can::AxisConfig& a = config_.axis(i);
    goal_counts_[i] = a.toCounts(q[i]);
    if (goal_counts_[i] == axes_[i]->positionCounts()) continue;
    started_axes_ |= 1u << i;
    // Round up, so an axis with a short way is never the one arriving late.
    const std::array<std::uint32_t, 3> values = {
        static_cast<std::uint32_t>(std::max(1.0, std::ceil(profile_.velocity[i] * a.counts_per_metre))),
        static_cast<std::uint32_t>(std::max(1.0, std::ceil(profile_.acceleration[i] * a.counts_per_metre))),
        static_cast<std::uint32_t>(std::max(1.0, std::ceil(profile_.acceleration[i] * a.counts_per_metre)))};
    const std::array<std::uint16_t, 3> objects = {0x6081, 0x6083, 0x6084};
    for (int k = 0; k < 3; ++k) {
      if (written_profile_[i] && (*written_profile_[i])[k] == values[k]) continue;
      ++sdo_pending_;
      master_->sdoDownload(a.node_id, objects[k], 0, can::toBytes(values[k], 4), [this, gen](const can::SdoResult& r) {
        if (gen != sdo_generation_) return;
        --sdo_pending_;
        if (!r.ok && sdo_error_.empty()) sdo_error_ = r.error;
      });
    }
    written_profile_[i] = values;
  }
  phase_ = Phase::kProfiles;
}

// --- commands ------------------------------------------------------------------------------------------

Accepted Controller::refuse(const std::string& why) {
  last_error_ = why;
  log("refused: " + why);
  return {0, why};
}

std::string Controller::refusal(bool needs_homed) const {
  switch (mode_) {
    case Mode::kStarting:
      return "the drives are not up yet (bringing up the CAN nodes)";
    case Mode::kEstop:
      return "the e-stop is latched: release it and call reset_fault";
    case Mode::kReleasing:
      return "the e-stop is latched (the tool is backing off the body): release it and call reset_fault";
    case Mode::kFault: {
      std::string f;
      for (const auto& s : faults_) f += (f.empty() ? "" : "; ") + s;
      return "the arm is in fault (" + f + "): call reset_fault";
    }
    case Mode::kHoming:
    case Mode::kMoving:
    case Mode::kMassaging:
    case Mode::kStopping:
    case Mode::kResetting:
      return std::string("busy: ") + toString(mode_) +
             (current_ && !current_->step.label.empty() ? " (" + current_->step.label + ")" : "") + "; call stop first";
    default:
      break;
  }
  if (needs_homed && !allHomed()) return "not homed: call home first (no motion before homing)";
  return "";
}

Accepted Controller::begin(Mode mode, std::deque<Action> actions, const std::string& what) {
  command_ = next_id_++;
  results_[command_] = CommandResult{};
  while (results_.size() > 200) results_.erase(results_.begin());
  command_what_ = what;
  queue_ = std::move(actions);
  current_.reset();
  aborting_ = false;
  abort_reason_.clear();
  presses_done_ = 0;
  mode_ = mode;
  last_keepalive_ = clock_.now();
  log("command " + std::to_string(command_) + ": " + what);
  return {command_, ""};
}

void Controller::setResult(std::uint64_t id, bool success, const std::string& message) {
  CommandResult& r = results_[id];
  r.done = true;
  r.success = success;
  r.message = message;
}

void Controller::finish(bool success, const std::string& message) {
  in_contact_ = calibrating_force_ = false;
  const auto it = results_.find(command_);
  if (it == results_.end() || it->second.done) return;
  setResult(command_, success, message);
  if (!success) last_error_ = message;
  log("command " + std::to_string(command_) + " (" + command_what_ + ") " + (success ? "done: " : "failed: ") +
      message);
}

Accepted Controller::home() {
  Lock lock(master_->mutex());
  if (std::string why = refusal(false); !why.empty()) return refuse("home refused: " + why);
  Action enable{Action::Kind::kEnableAll};
  Action z{Action::Kind::kHome, 0b100};
  Action xy{Action::Kind::kHome, 0b011};
  std::deque<Action> actions{enable, z, xy};
  for (Action& a : forceCalibration()) actions.push_back(std::move(a));
  return begin(Mode::kHoming, std::move(actions), "home");
}

std::deque<Controller::Action> Controller::forceCalibration() const {
  std::deque<Action> out;
  if (!tool_force_->enabled()) return out;
  Eigen::Vector3d home;
  for (int i = 0; i < 3; ++i) home[i] = config_.axis(i).home_offset;
  const Eigen::Vector3d top = config_.toolOf(home), low = top - Eigen::Vector3d(0, 0, config_.force.calibration_travel);
  for (double speed : config_.force.calibration_speeds) {
    for (const Eigen::Vector3d& goal : {low, top}) {
      Action a{Action::Kind::kStep};
      a.step.tool = goal;
      a.step.speed = speed;
      a.step.label = "force calibration: z to " + fmt("%.3f", goal.z()) + " m at " + fmt("%.3f", speed) + " m/s";
      a.step.force_calibration = true;
      out.push_back(std::move(a));
    }
  }
  return out;
}

void Controller::senseForce(can::TimePoint now) {
  if (!tool_force_->enabled()) return;
  const bool calibrating = current_ && current_->kind == Action::Kind::kStep && current_->step.force_calibration;
  tool_force_->update(master_->feedback(config_.axis(2).node_id), axes_[2]->position(), now, calibrating);
}

void Controller::finishForceCalibration() {
  const std::string why = tool_force_->finishCalibration();
  const ForceReading r = tool_force_->reading();
  log(why.empty() ? "force calibrated: moving mass " + fmt("%.2f", r.baseline.mass) + " kg, friction " +
                        fmt("%.1f", r.baseline.coulomb) + " N + " + fmt("%.0f", r.baseline.viscous) + " N s/m"
                  : "force " + why);
}

Accepted Controller::moveTo(const Eigen::Vector3d& tool, double speed) {
  Lock lock(master_->mutex());
  if (std::string why = refusal(true); !why.empty()) return refuse("move refused: " + why);
  if (std::string bad = checkTool(config_, tool); !bad.empty()) return refuse("move refused: the target " + bad);
  if (!std::isfinite(speed) || speed < 0.0) return refuse("move refused: speed must be >= 0 m/s (0: the joint limits)");
  if (const double fastest = maxLineSpeed(config_); speed > fastest) {
    return refuse("move refused: speed " + fmt("%g", speed) + " m/s is beyond what the joints allow (" +
                  fmt("%.3f", fastest) + " m/s; 0: as fast as they allow)");
  }
  Action enable{Action::Kind::kEnableAll};
  Action move{Action::Kind::kStep};
  move.step.tool = tool;
  move.step.speed = speed;
  move.step.label = "move to " + formatPoint(tool);
  return begin(Mode::kMoving, {enable, move}, "move");
}

Accepted Controller::massage(const PressRequest& request) {
  Lock lock(master_->mutex());
  if (std::string why = refusal(true); !why.empty()) return refuse("massage refused: " + why);
  std::vector<Step> steps;
  if (std::string why = planMassage(config_, config_.toolOf(joints()), request, &steps); !why.empty()) {
    return refuse("massage refused: " + why);
  }
  std::deque<Action> actions{Action{Action::Kind::kEnableAll}};
  for (Step& s : steps) {
    Action a{Action::Kind::kStep};
    a.step = std::move(s);
    actions.push_back(std::move(a));
  }
  return begin(Mode::kMassaging, std::move(actions), "massage");
}

void Controller::stopAndReenable(const std::string& why) {
  aborting_ = true;
  abort_reason_ = why;
  queue_ = {Action{Action::Kind::kQuickStopAll}, Action{Action::Kind::kEnableAll}, Action{Action::Kind::kProfileMode}};
  current_.reset();
  mode_ = Mode::kStopping;
}

void Controller::retract(const std::string& why) {
  if (current_ && current_->kind == Action::Kind::kStep && current_->step.kind == Step::Kind::kForcePress) {
    abortForcePress(why);
    return;
  }
  const Step from = current_->step;
  aborting_ = true;
  abort_reason_ = why;
  queue_.clear();
  for (Step& s : retractSteps(config_, from)) {
    Action a{Action::Kind::kStep};
    a.step = std::move(s);
    queue_.push_back(std::move(a));
  }
  current_.reset();
  log("retracting: " + why);
}

Accepted Controller::stop(const std::string& why) {
  Lock lock(master_->mutex());
  const auto it = results_.find(command_);
  const bool running = it != results_.end() && !it->second.done;
  if (!running || mode_ == Mode::kFault || mode_ == Mode::kEstop || mode_ == Mode::kResetting) {
    const Accepted a{next_id_++, ""};
    setResult(a.id, true, std::string("nothing to stop (") + toString(mode_) + ")");
    return a;
  }
  if (!aborting_) {
    if (mode_ == Mode::kMassaging && current_ && current_->kind == Action::Kind::kStep && current_->step.contact) {
      retract(why);
    } else {
      stopAndReenable(why);
    }
  }
  return {command_, ""};
}

Accepted Controller::resetFault() {
  Lock lock(master_->mutex());
  if (estop_input_) return refuse("reset refused: the e-stop is still pressed: release it first");
  if (mode_ == Mode::kReleasing) return refuse("reset refused: the tool is still backing off the body; retry after");
  if (mode_ != Mode::kFault && mode_ != Mode::kEstop) {
    const Accepted a{next_id_++, ""};
    setResult(a.id, true, std::string("nothing to reset (") + toString(mode_) + ")");
    return a;
  }
  const can::BusState bs = bus_.status().state;
  if (bs == can::BusState::kBusOff || bs == can::BusState::kDown) {
    return refuse("reset refused: the CAN bus " + bus_.name() + " is still " + can::toString(bs));
  }
  for (int i = 0; i < 3; ++i) {
    const can::AxisConfig& a = config_.axis(i);
    const can::NodeState ns = master_->nodeState(a.node_id);
    if (ns == can::NodeState::kFailed) {
      master_->bringUp(a.node_id);
      return refuse("reset refused: " + axisLabel(a) + " failed its bring-up; bringing it up again, retry");
    }
    if (ns != can::NodeState::kOperational) {
      return refuse("reset refused: " + axisLabel(a) + " is " + can::toString(ns) + " (no heartbeat / not up)");
    }
  }
  faults_.clear();
  estop_latched_ = false;
  for (auto& w : written_profile_) w.reset();
  return begin(
      Mode::kResetting,
      {Action{Action::Kind::kFaultResetAll}, Action{Action::Kind::kEnableAll}, Action{Action::Kind::kProfileMode}},
      "reset");
}

void Controller::setEstop(bool pressed) {
  Lock lock(master_->mutex());
  const bool was = estop_input_;
  estop_input_ = pressed;
  if (!pressed) {
    if (was) log(estop_latched_ ? "e-stop released (latched until reset_fault)" : "e-stop released");
    return;
  }
  if (estop_latched_) return;
  estop_latched_ = true;
  // A press in contact: the step to back off from, before the queue is cleared.
  std::optional<Step> release_from;
  if (config_.press.estop_release && mode_ == Mode::kMassaging && current_ && current_->kind == Action::Kind::kStep &&
      current_->step.contact) {
    release_from = current_->step;
  }
  // The quick-stop controlword leaves at once (RPDO1 with the last target);
  // the axes keep sending it with every SYNC.
  for (int i = 0; i < 3; ++i) {
    if (master_->nodeState(config_.axis(i).node_id) != can::NodeState::kOperational) continue;
    axes_[i]->quickStopNow();
  }
  finish(false, release_from ? "e-stop pressed: the tool backs off to the approach point" : "e-stop pressed");
  queue_.clear();
  current_.reset();
  aborting_ = false;
  last_error_ = "e-stop pressed";
  mode_ = Mode::kEstop;
  log("E-STOP: quick stop sent to every drive; latched until reset_fault");
  if (release_from) startRelease(*release_from);
}

void Controller::startRelease(const Step& from) {
  // Once the quick stops have completed: the drives enabled again, one slow
  // straight move back to the press's approach point (its retreat), then
  // stopped and latched (runQueue). A fault on the way stops everything.
  Step back = retractSteps(config_, from).front();
  back.label = "e-stop: releasing the pressure";
  if (from.kind == Step::Kind::kForcePress && press_) {
    // Straight up from where the tool presses (a stroke may be anywhere along its path), to the approach height
    // over the skin there.
    const Eigen::Vector3d at = config_.toolOf(joints());
    back.tool = Eigen::Vector3d(at.x(), at.y(), std::max(at.z(), press_->backOffZ()));
  }
  queue_ = {Action{Action::Kind::kWaitStopped}, Action{Action::Kind::kEnableAll}, Action{Action::Kind::kProfileMode}};
  Action a{Action::Kind::kStep};
  a.step = back;
  queue_.push_back(a);
  mode_ = Mode::kReleasing;
  log("E-STOP during a press: backing off to " + formatPoint(back.tool) + " at " + fmt("%.3f", back.speed) + " m/s");
}

void Controller::setSensorForce(double force) {
  Lock lock(master_->mutex());
  tool_force_->setSensorForce(force, clock_.now());
}

void Controller::keepAlive() {
  Lock lock(master_->mutex());
  last_keepalive_ = clock_.now();
}

void Controller::abortMassage(const std::string& reason) {
  Lock lock(master_->mutex());
  if (mode_ != Mode::kMassaging || aborting_) return;
  log("massage aborted: " + reason);
  if (current_ && current_->kind == Action::Kind::kStep && current_->step.contact) {
    retract("massage aborted: " + reason);
  } else {
    stopAndReenable("massage aborted: " + reason);
  }
}

CommandResult Controller::result(std::uint64_t id) const {
  Lock lock(master_->mutex());
  const auto it = results_.find(id);
  if (it == results_.end()) return CommandResult{true, false, "unknown command id " + std::to_string(id)};
  return it->second;
}

Mode Controller::mode() const {
  Lock lock(master_->mutex());
  return mode_;
}

ArmStatus Controller::status() const {
  Lock lock(master_->mutex());
  ArmStatus s;
  s.mode = mode_;
  s.homed = allHomed();
  s.estop_input = estop_input_;
  s.estop_latched = estop_latched_;
  for (int i = 0; i < 3; ++i) {
    const can::AxisConfig& a = config_.axis(i);
    AxisStatus& as = s.axes[i];
    as.name = a.name;
    as.valid = axes_[i]->valid();
    as.position = axes_[i]->position();
    as.state = axes_[i]->state();
    as.node = master_->nodeState(a.node_id);
    as.statusword = axes_[i]->statusword();
    as.homed = axes_[i]->homed();
    s.joints[i] = as.position;
  }
  s.tool = config_.toolOf(s.joints);
  s.force = tool_force_->reading();
  s.faults = faults_;
  if (current_) {
    switch (current_->kind) {
      case Action::Kind::kEnableAll:
        s.activity = "enabling the drives";
        break;
      case Action::Kind::kQuickStopAll:
        s.activity = "quick stop";
        break;
      case Action::Kind::kFaultResetAll:
        s.activity = "fault reset";
        break;
      case Action::Kind::kHome:
        s.activity = current_->mask == 0b100 ? "homing Z" : "homing X, Y";
        break;
      case Action::Kind::kStep:
        s.activity = current_->step.label;
        if (current_->step.kind == Step::Kind::kForcePress && press_) {
          s.activity += ": " + press_->describe();
          s.press_phase = toString(press_->phase());
          s.force_target = press_->setPoint();
          s.force_limit = press_->limit();
          s.force_zero = press_->zero();
        }
        break;
      case Action::Kind::kWaitStopped:
        s.activity = "waiting for the axes to stop";
        break;
      case Action::Kind::kProfileMode:
        s.activity = "back to profile position";
        break;
    }
    if (current_->kind == Action::Kind::kStep) s.target = current_->step.target;
  }
  s.last_error = last_error_;
  s.bus = bus_.status().state;
  s.cycles = cycles_;
  s.command = command_;
  s.presses_done = presses_done_;
  return s;
}

Health health(const ArmStatus& s) {
  using Level = Health::Level;
  if (s.mode == Mode::kFault) {
    std::string f;
    for (const auto& x : s.faults) f += (f.empty() ? "" : "; ") + x;
    return {Level::kError, "fault: " + f};
  }
  if (s.mode == Mode::kEstop) return {Level::kError, "e-stop latched"};
  if (s.mode == Mode::kReleasing) return {Level::kError, "e-stop latched, releasing the pressure"};
  if (!s.homed || s.mode == Mode::kStarting) return {Level::kWarn, std::string(toString(s.mode)) + ": not homed"};
  return {Level::kOk, toString(s.mode)};
}

std::string formatForce(const ForceReading& force) { return fmt("%.1f N", force.force) + " (" + force.source + ")"; }

std::string describeAxis(const AxisStatus& a) {
  char position[48];
  std::snprintf(position, sizeof position, "%.6f m", a.position);
  return std::string(position) + ", " + can::toString(a.state) + ", node " + can::toString(a.node) +
         (a.homed ? ", homed" : ", not homed");
}

}  // namespace massage_cell::arm
