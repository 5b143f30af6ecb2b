// SocketCAN endpoint with error decoding and bus-off recovery (see socketcan_bus.h).
#include "massage_cell/can/socketcan_bus.h"

#include <fcntl.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <net/if_arp.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <thread>

namespace massage_cell::can {

namespace {

std::string errnoText(int err) { return std::strerror(err); }

}  // namespace

ErrorFrameInfo decodeErrorFrame(const can_frame& frame) {
  ErrorFrameInfo info;
  if (!(frame.can_id & CAN_ERR_FLAG)) return info;
  info.valid = true;
  const canid_t c = frame.can_id & CAN_ERR_MASK;
  std::vector<std::string> parts;
  if (c & CAN_ERR_TX_TIMEOUT) parts.push_back("tx timeout");
  if (c & CAN_ERR_LOSTARB) parts.push_back("lost arbitration");
  if (c & CAN_ERR_CRTL) {
    const std::uint8_t d = frame.len > 1 ? frame.data[1] : 0;
    std::string s = "controller:";
    if (d & CAN_ERR_CRTL_RX_OVERFLOW) s += " rx overflow";
    if (d & CAN_ERR_CRTL_TX_OVERFLOW) s += " tx overflow";
    if (d & CAN_ERR_CRTL_RX_WARNING) s += " rx error-warning";
    if (d & CAN_ERR_CRTL_TX_WARNING) s += " tx error-warning";
    if (d & CAN_ERR_CRTL_RX_PASSIVE) s += " rx error-passive";
    if (d & CAN_ERR_CRTL_TX_PASSIVE) s += " tx error-passive";
    if (d & CAN_ERR_CRTL_ACTIVE) s += " back to error-active";
    parts.push_back(s);
    if (d & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) {
      info.state = BusState::kErrorPassive;
    } else if (d & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) {
      info.state = BusState::kErrorWarning;
    } else if (d & CAN_ERR_CRTL_ACTIVE) {
      info.state = BusState::kErrorActive;
    }
  }
  if (c & CAN_ERR_PROT) parts.push_back("protocol violation");
  if (c & CAN_ERR_TRX) parts.push_back("transceiver status");
  if (c & CAN_ERR_ACK) parts.push_back("no ACK on transmission");
  if (c & CAN_ERR_BUSERROR) parts.push_back("bus error");
  if (c & CAN_ERR_RESTARTED) {
    parts.push_back("controller restarted");
    info.state = BusState::kErrorActive;
  }
  if (c & CAN_ERR_BUSOFF) {
    parts.push_back("bus-off");
    info.state = BusState::kBusOff;
  }
  for (std::size_t i = 0; i < parts.size(); ++i) info.text += (i ? "; " : "") + parts[i];
  if (info.text.empty()) info.text = "error frame without class bits";
  return info;
}

Duration Backoff::next() {
  const Duration d = next_;
  next_ = std::min(max_, next_ * 2);
  return d;
}

SocketCanBus::SocketCanBus(SocketCanOptions options)
    : options_(std::move(options)), backoff_(options_.reopen_initial, options_.reopen_max) {
  if (options_.interface.empty()) throw BusError("SocketCAN: no interface name given");
  if (options_.interface.size() >= IFNAMSIZ) {
    throw BusError("SocketCAN interface '" + options_.interface + "': name longer than " +
                   std::to_string(IFNAMSIZ - 1) + " characters");
  }
  fd_ = openSocket();
  active_since_ = SteadyClock::instance().now();
}

SocketCanBus::~SocketCanBus() {
  if (fd_ >= 0) ::close(fd_);
}

int SocketCanBus::openSocket() {
  const std::string& ifname = options_.interface;
  // Look the interface up first (on a plain local socket, so the error names
  // a missing interface even where PF_CAN itself is unavailable).
  ifreq ifr{};
  std::strncpy(ifr.ifr_name, ifname.c_str(), IFNAMSIZ - 1);
  {
    const int probe = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (probe < 0) throw BusError("SocketCAN interface '" + ifname + "': socket(AF_UNIX) failed: " + errnoText(errno));
    if (::ioctl(probe, SIOCGIFINDEX, &ifr) < 0) {
      const int err = errno;
      ::close(probe);
      if (err == ENODEV) {
        throw BusError("SocketCAN interface '" + ifname + "' does not exist (ioctl SIOCGIFINDEX: " + errnoText(err) +
                       "); create it, e.g. `ip link add dev " + ifname + " type vcan && ip link set up " + ifname +
                       "`");
      }
      throw BusError("SocketCAN interface '" + ifname + "': ioctl SIOCGIFINDEX failed: " + errnoText(err));
    }
    ifreq hw = ifr;
    if (::ioctl(probe, SIOCGIFHWADDR, &hw) == 0 && hw.ifr_hwaddr.sa_family != ARPHRD_CAN) {
      ::close(probe);
      throw BusError("SocketCAN interface '" + ifname + "' is not a CAN interface (link type " +
                     std::to_string(hw.ifr_hwaddr.sa_family) + ", CAN is " + std::to_string(ARPHRD_CAN) + ")");
    }
    ifreq flags = ifr;
    if (::ioctl(probe, SIOCGIFFLAGS, &flags) == 0 &&
        (!(flags.ifr_flags & IFF_UP) || !(flags.ifr_flags & IFF_RUNNING))) {
      ::close(probe);
      throw BusError("SocketCAN interface '" + ifname + "' is " +
                     ((flags.ifr_flags & IFF_UP) ? "up but not running (no carrier: bus-off?)" : "down") +
                     "; bring it up with `ip link set up " + ifname + "`");
    }
    ::close(probe);
  }
  const int ifindex = ifr.ifr_ifindex;
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    throw BusError("SocketCAN interface '" + ifname + "': socket(PF_CAN, SOCK_RAW, CAN_RAW) failed: " +
                   errnoText(errno) + " (is the can / can_raw kernel module loaded?)");
  }
  auto fail = [&](const std::string& what) {
    const int err = errno;
    ::close(fd);
    throw BusError("SocketCAN interface '" + ifname + "': " + what + ": " + errnoText(err));
  };
  const int loopback = options_.loopback ? 1 : 0;
  const int own = options_.receive_own ? 1 : 0;
  const int one = 1;
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_LOOPBACK, &loopback, sizeof loopback) < 0) fail("CAN_RAW_LOOPBACK");
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &own, sizeof own) < 0) fail("CAN_RAW_RECV_OWN_MSGS");
  const auto& filters = options_.filters;
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, filters.empty() ? nullptr : filters.data(),
                   static_cast<socklen_t>(filters.size() * sizeof(can_filter))) < 0) {
    fail("CAN_RAW_FILTER");
  }
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &options_.error_mask, sizeof options_.error_mask) < 0) {
    fail("CAN_RAW_ERR_FILTER");
  }
  if (::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMP, &one, sizeof one) < 0) fail("SO_TIMESTAMP");
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifindex;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) fail("bind");
  return fd;
}

void SocketCanBus::noteState(BusState state, const std::string& text) {
  std::lock_guard<std::mutex> lock(status_mutex_);
  if (state == BusState::kBusOff && status_.state != BusState::kBusOff) ++status_.bus_off_events;
  if (state == BusState::kErrorActive && (status_.state == BusState::kBusOff || status_.state == BusState::kDown)) {
    ++status_.recoveries;
    active_since_ = SteadyClock::instance().now();
  }
  status_.state = state;
  if (!text.empty()) status_.last_error = text;
}

void SocketCanBus::requestReopen(const std::string& reason, BusState state) {
  noteState(state, options_.interface + ": " + reason + "; reopening the socket with back-off");
  reopen_requested_ = true;
}

bool SocketCanBus::reopenIfDue() {
  if (!reopen_requested_) return true;
  std::unique_lock<std::shared_mutex> lock(fd_mutex_);
  if (!reopen_requested_) return fd_ >= 0;
  const TimePoint now = SteadyClock::instance().now();
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
    // Stable for a long while before this failure: start the back-off over.
    if (now - active_since_ > options_.reopen_max * 2) backoff_.reset();
    next_reopen_ = now + backoff_.next();
    return false;
  }
  if (now < next_reopen_) return false;
  try {
    fd_ = openSocket();
  } catch (const BusError& e) {
    next_reopen_ = now + backoff_.next();
    std::lock_guard<std::mutex> slock(status_mutex_);
    status_.last_error = std::string(e.what()) + " (retrying)";
    return false;
  }
  reopen_requested_ = false;
  noteState(BusState::kErrorActive, "");
  return true;
}

bool SocketCanBus::send(const can_frame& frame) {
  auto failed = [&](const std::string& why) {
    std::lock_guard<std::mutex> lock(status_mutex_);
    ++status_.tx_failed;
    status_.last_error = options_.interface + ": send failed: " + why;
    return false;
  };
  if (!reopenIfDue()) return failed(std::string("interface ") + toString(status().state) + ", reopen pending");
  std::shared_lock<std::shared_mutex> lock(fd_mutex_);
  if (fd_ < 0) return failed("socket closed");
  const ssize_t n = ::write(fd_, &frame, sizeof frame);
  if (n == static_cast<ssize_t>(sizeof frame)) {
    std::lock_guard<std::mutex> slock(status_mutex_);
    ++status_.tx_frames;
    return true;
  }
  const int err = n < 0 ? errno : EIO;
  lock.unlock();
  if (err == ENETDOWN || err == ENODEV || err == ENXIO) {
    requestReopen("interface went down (" + errnoText(err) + ")", BusState::kDown);
  }
  if (err == EAGAIN || err == ENOBUFS) return failed("transmit queue full (" + errnoText(err) + ")");
  return failed(errnoText(err));
}

std::optional<TimedFrame> SocketCanBus::receive(Duration timeout) {
  const auto& clock = SteadyClock::instance();
  const TimePoint deadline = clock.now() + timeout;
  while (true) {
    const TimePoint now = clock.now();
    const Duration left = std::max(Duration::zero(), deadline - now);
    if (!reopenIfDue()) {
      if (left <= Duration::zero()) return std::nullopt;
      std::this_thread::sleep_for(std::min<Duration>(left, std::chrono::milliseconds(10)));
      continue;
    }
    std::shared_lock<std::shared_mutex> lock(fd_mutex_);
    if (fd_ < 0) {
      if (left <= Duration::zero()) return std::nullopt;
      continue;
    }
    pollfd p{fd_, POLLIN, 0};
    const Duration wait = std::min<Duration>(left, std::chrono::milliseconds(50));
    timespec ts{static_cast<time_t>(wait.count() / 1'000'000'000), static_cast<long>(wait.count() % 1'000'000'000)};
    const int r = ::ppoll(&p, 1, &ts, nullptr);
    if (r < 0 && errno != EINTR) {
      const int err = errno;
      lock.unlock();
      requestReopen("ppoll failed: " + errnoText(err), BusState::kDown);
      continue;
    }
    if (r > 0 && (p.revents & (POLLERR | POLLHUP | POLLNVAL)) && !(p.revents & POLLIN)) {
      lock.unlock();
      requestReopen("socket error (interface removed or down)", BusState::kDown);
      continue;
    }
    if (r > 0 && (p.revents & POLLIN)) {
      can_frame frame{};
      iovec iov{&frame, sizeof frame};
      alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timeval))];
      msghdr msg{};
      msg.msg_iov = &iov;
      msg.msg_iovlen = 1;
      msg.msg_control = control;
      msg.msg_controllen = sizeof control;
      const ssize_t n = ::recvmsg(fd_, &msg, 0);
      if (n < 0) {
        const int err = errno;
        if (err == EAGAIN || err == EINTR) continue;
        lock.unlock();
        requestReopen("recvmsg failed: " + errnoText(err), BusState::kDown);
        continue;
      }
      if (n != static_cast<ssize_t>(sizeof frame)) continue;  // CAN FD frames are not enabled; ignore anything else
      TimePoint stamp = clock.now();
      for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMP) {
          timeval tv{};
          std::memcpy(&tv, CMSG_DATA(c), sizeof tv);
          const auto kernel = std::chrono::seconds(tv.tv_sec) + std::chrono::microseconds(tv.tv_usec);
          const auto wall = std::chrono::system_clock::now().time_since_epoch();
          stamp -= std::chrono::duration_cast<Duration>(wall - kernel);  // age of the frame on the steady clock
        }
      }
      if (frame.can_id & CAN_ERR_FLAG) {
        const ErrorFrameInfo info = decodeErrorFrame(frame);
        {
          std::lock_guard<std::mutex> slock(status_mutex_);
          ++status_.error_frames;
        }
        lock.unlock();
        if (info.state == BusState::kBusOff) {
          requestReopen(info.text, BusState::kBusOff);
        } else {
          BusState s;
          {
            std::lock_guard<std::mutex> slock(status_mutex_);
            s = info.state.value_or(status_.state);
          }
          noteState(s, options_.interface + ": " + info.text);
        }
        continue;
      }
      std::lock_guard<std::mutex> slock(status_mutex_);
      ++status_.rx_frames;
      return TimedFrame{frame, stamp};
    }
    if (clock.now() >= deadline) return std::nullopt;
  }
}

void SocketCanBus::setFilters(const std::vector<can_filter>& filters) {
  std::unique_lock<std::shared_mutex> lock(fd_mutex_);
  options_.filters = filters;
  if (fd_ >= 0 && ::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, filters.empty() ? nullptr : filters.data(),
                               static_cast<socklen_t>(filters.size() * sizeof(can_filter))) < 0) {
    throw BusError("SocketCAN interface '" + options_.interface + "': CAN_RAW_FILTER: " + errnoText(errno));
  }
}

BusStatus SocketCanBus::status() const {
  std::lock_guard<std::mutex> lock(status_mutex_);
  return status_;
}

}  // namespace massage_cell::can
