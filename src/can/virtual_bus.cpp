// In-process CAN hub with SocketCAN loopback semantics (see virtual_bus.h).
#include "massage_cell/can/virtual_bus.h"

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <random>

namespace massage_cell::can {

struct VirtualBus::Hub {
  struct Port {
    std::deque<TimedFrame> queue;
    std::condition_variable cv;
    std::vector<can_filter> filters = acceptAllFilters();
    bool loopback = true;
    bool receive_own = false;
    TimePoint bus_off_until{};
    bool was_off = false;
    BusStatus status;
  };
  struct DropRule {
    int count;
    std::function<bool(const can_frame&)> match;
  };

  Hub(const Clock& c, std::size_t limit) : clock(c), queue_limit(limit) {}

  const Clock& clock;
  const std::size_t queue_limit;
  mutable std::mutex mutex;
  std::map<const Endpoint*, std::unique_ptr<Port>> ports;
  TimePoint bus_off_until{};
  std::vector<DropRule> drop_rules;
  double drop_probability = 0.0;
  std::mt19937 rng{1};
  std::uint64_t dropped = 0;
  std::uint64_t sent = 0;

  // Bus-off bookkeeping of one port at `now` (counts transitions). Caller holds the mutex.
  bool refresh(Port& p, TimePoint now) {
    const bool off = now < std::max(p.bus_off_until, bus_off_until);
    if (off && !p.was_off) {
      p.was_off = true;
      ++p.status.bus_off_events;
      p.status.last_error = "bus-off (fault injected on the virtual bus)";
    } else if (!off && p.was_off) {
      p.was_off = false;
      ++p.status.recoveries;
    }
    p.status.state = off ? BusState::kBusOff : BusState::kErrorActive;
    return off;
  }

  bool shouldDrop(const can_frame& frame) {
    for (auto it = drop_rules.begin(); it != drop_rules.end(); ++it) {
      if (!it->match || it->match(frame)) {
        if (--it->count <= 0) drop_rules.erase(it);
        return true;
      }
    }
    if (drop_probability > 0.0) {
      std::uniform_real_distribution<double> u(0.0, 1.0);
      if (u(rng) < drop_probability) return true;
    }
    return false;
  }
};

VirtualBus::Endpoint::Endpoint(std::shared_ptr<Hub> hub, std::string name)
    : hub_(std::move(hub)), name_(std::move(name)) {
  std::lock_guard<std::mutex> lock(hub_->mutex);
  hub_->ports[this] = std::make_unique<Hub::Port>();
}

VirtualBus::Endpoint::~Endpoint() {
  std::lock_guard<std::mutex> lock(hub_->mutex);
  hub_->ports.erase(this);
}

bool VirtualBus::Endpoint::send(const can_frame& frame) {
  std::lock_guard<std::mutex> lock(hub_->mutex);
  const TimePoint now = hub_->clock.now();
  Hub::Port& self = *hub_->ports.at(this);
  if (hub_->refresh(self, now)) {
    ++self.status.tx_failed;
    self.status.last_error = "send failed: " + name_ + " is bus-off";
    return false;
  }
  if (frame.len > CAN_MAX_DLEN) {
    ++self.status.tx_failed;
    self.status.last_error = "send failed: DLC " + std::to_string(frame.len) + " > 8";
    return false;
  }
  ++self.status.tx_frames;
  ++hub_->sent;
  if (hub_->shouldDrop(frame)) {
    ++hub_->dropped;
    return true;  // on the wire as far as the sender knows; nobody receives it
  }
  for (auto& [endpoint, port] : hub_->ports) {
    const bool own = endpoint == this;
    if (!self.loopback) continue;  // no local delivery at all (vcan semantics)
    if (own && !self.receive_own) continue;
    if (hub_->refresh(*port, now)) continue;
    if (!matchesFilters(frame, port->filters)) continue;
    if (port->queue.size() >= hub_->queue_limit) {
      ++port->status.rx_overflow;
      continue;
    }
    port->queue.push_back(TimedFrame{frame, now});
    port->cv.notify_all();
  }
  return true;
}

std::optional<TimedFrame> VirtualBus::Endpoint::receive(Duration timeout) {
  std::unique_lock<std::mutex> lock(hub_->mutex);
  Hub::Port& self = *hub_->ports.at(this);
  if (self.queue.empty() && timeout > Duration::zero()) {
    self.cv.wait_for(lock, timeout, [&] { return !self.queue.empty(); });
  }
  hub_->refresh(self, hub_->clock.now());
  if (self.queue.empty()) return std::nullopt;
  TimedFrame f = self.queue.front();
  self.queue.pop_front();
  ++self.status.rx_frames;
  return f;
}

void VirtualBus::Endpoint::setFilters(const std::vector<can_filter>& filters) {
  std::lock_guard<std::mutex> lock(hub_->mutex);
  hub_->ports.at(this)->filters = filters;
}

BusStatus VirtualBus::Endpoint::status() const {
  std::lock_guard<std::mutex> lock(hub_->mutex);
  Hub::Port& self = *hub_->ports.at(this);
  hub_->refresh(self, hub_->clock.now());
  return self.status;
}

void VirtualBus::Endpoint::setLoopback(bool on) {
  std::lock_guard<std::mutex> lock(hub_->mutex);
  hub_->ports.at(this)->loopback = on;
}

void VirtualBus::Endpoint::setReceiveOwn(bool on) {
  std::lock_guard<std::mutex> lock(hub_->mutex);
  hub_->ports.at(this)->receive_own = on;
}

std::size_t VirtualBus::Endpoint::pending() const {
  std::lock_guard<std::mutex> lock(hub_->mutex);
  return hub_->ports.at(this)->queue.size();
}

VirtualBus::VirtualBus(const Clock& clock, std::size_t queue_limit) : hub_(std::make_shared<Hub>(clock, queue_limit)) {}

VirtualBus::~VirtualBus() = default;

std::shared_ptr<VirtualBus::Endpoint> VirtualBus::open(const std::string& name) {
  return std::make_shared<Endpoint>(hub_, name);
}

void VirtualBus::setBusOff(Duration duration) {
  std::lock_guard<std::mutex> lock(hub_->mutex);
  const TimePoint now = hub_->clock.now();
  hub_->bus_off_until = now + duration;
  for (auto& [endpoint, port] : hub_->ports) {
    (void)endpoint;
    port->queue.clear();  // frames in flight are lost
    hub_->refresh(*port, now);
  }
}

void VirtualBus::setBusOff(const Endpoint& endpoint, Duration duration) {
  std::lock_guard<std::mutex> lock(hub_->mutex);
  const TimePoint now = hub_->clock.now();
  Hub::Port& port = *hub_->ports.at(&endpoint);
  port.bus_off_until = now + duration;
  port.queue.clear();
  hub_->refresh(port, now);
}

void VirtualBus::dropNext(int count, std::function<bool(const can_frame&)> match) {
  if (count <= 0) return;
  std::lock_guard<std::mutex> lock(hub_->mutex);
  hub_->drop_rules.push_back({count, std::move(match)});
}

void VirtualBus::setDropProbability(double p, std::uint32_t seed) {
  std::lock_guard<std::mutex> lock(hub_->mutex);
  hub_->drop_probability = std::clamp(p, 0.0, 1.0);
  hub_->rng.seed(seed);
}

std::uint64_t VirtualBus::dropped() const {
  std::lock_guard<std::mutex> lock(hub_->mutex);
  return hub_->dropped;
}

std::uint64_t VirtualBus::sent() const {
  std::lock_guard<std::mutex> lock(hub_->mutex);
  return hub_->sent;
}

}  // namespace massage_cell::can
