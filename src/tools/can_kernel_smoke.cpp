// can_kernel_smoke: checks the kernel's SocketCAN (CAN_RAW) behaviour the CAN
// motion stack relies on, on a real interface (vcan0 under qemu: see
// scripts/qemu_can/run.sh). Plain C++17 + Linux headers, no project libraries,
// meant to be linked statically and run inside the qemu guest.
//
//   can_kernel_smoke [--iface vcan0] [--frames 1000] [--max-p99-us N] [--peer N]
//   can_kernel_smoke --serve [--iface vcan0]
//
// --serve runs an echo responder (another process, like a simulated drive):
// every frame with id 0x7E0 is answered with id 0x7E8 and the same payload,
// until SIGTERM/SIGINT (then exit 0). --peer N makes the checking process also
// do N request/reply round trips with such a responder (waiting up to 10 s for
// it to come up) and print their p50/p99: the cross-process path the CANopen
// master and the simulated drives use.
//
// Checks, in order:
//   1. the interface exists, is ARPHRD_CAN, is up, has the CAN MTU (16) or the
//      CAN FD MTU (72: vcan's default);
//   2. loopback semantics: another socket on the host sees a sent frame
//      (CAN_RAW_LOOPBACK default on), the sender does not (CAN_RAW_RECV_OWN_MSGS
//      default off); with RECV_OWN_MSGS on the sender gets its own frame flagged
//      MSG_CONFIRM; with LOOPBACK off the other socket sees nothing;
//   3. id/mask filters on the receiver: standard and extended ids, DLC 0 and 8,
//      arrive in send order with identical payloads and SO_TIMESTAMP stamps
//      (present, non-decreasing, close to the wall clock); filtered-out ids (a
//      standard id outside the mask, an extended id equal to a wanted standard
//      id) do not arrive; a frame with an invalid DLC is refused (EINVAL);
//   4. send -> receive latency over --frames frames (p50 / p99 / max in µs);
//   5. binding to a nonexistent interface fails with ENODEV (SIOCGIFINDEX of an
//      unknown name, bind() to an unused ifindex);
//   6. error frames (what the bus-off test of qemu_can_system relies on): vcan
//      itself never reports errors, but a CAN_RAW socket may write a frame
//      whose can_id has CAN_ERR_FLAG set, and af_can delivers it on vcan as an
//      error frame to the sockets whose CAN_RAW_ERR_FILTER mask has that error
//      class: CAN_ERR_BUSOFF reaches a socket with the full mask (CAN_ERR_MASK,
//      SocketCanBus's default) and one with only CAN_ERR_BUSOFF, even when its
//      CAN_RAW_FILTER receives no data frames; a CAN_ERR_CRTL frame (data[1]
//      CAN_ERR_CRTL_TX_PASSIVE) arrives with its payload intact, but not at the
//      CAN_ERR_BUSOFF-only socket; a socket with the default mask 0 and the
//      writer itself (RECV_OWN_MSGS off) get none; a data filter that accepts
//      everything never lets an error frame through without an error mask;
//   7. (--peer N) N round trips with a --serve process.
// Prints `CAN_KERNEL_SMOKE OK` and exits 0 when all pass; otherwise prints
// `CAN_KERNEL_SMOKE FAIL: <reason>` and exits 1.

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <net/if_arp.h>  // glibc header: linux/if_arp.h clashes with net/if.h
#include <poll.h>
#include <signal.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

struct Failure {
  std::string what;
};

[[noreturn]] void fail(const std::string& what) { throw Failure{what}; }

std::string errnoText(const char* call) { return std::string(call) + ": " + std::strerror(errno); }

class Socket {
 public:
  Socket() : fd_(::socket(PF_CAN, SOCK_RAW, CAN_RAW)) {
    if (fd_ < 0) {
      if (errno == EAFNOSUPPORT)
        fail("socket(PF_CAN): no CAN support in this kernel (EAFNOSUPPORT): run under scripts/qemu_can/run.sh");
      fail(errnoText("socket(PF_CAN, SOCK_RAW, CAN_RAW)"));
    }
  }
  ~Socket() {
    if (fd_ >= 0) ::close(fd_);
  }
  Socket(const Socket&) = delete;
  Socket& operator=(const Socket&) = delete;
  int fd() const { return fd_; }

  template <typename T>
  void setOpt(int level, int name, const T& value, const char* what) {
    if (::setsockopt(fd_, level, name, &value, sizeof value) != 0) fail(errnoText(what));
  }
  void setFilters(const std::vector<can_filter>& filters) {
    if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, filters.data(),
                     static_cast<socklen_t>(filters.size() * sizeof(can_filter))) != 0)
      fail(errnoText("setsockopt(CAN_RAW_FILTER)"));
  }
  int bindTo(int ifindex) {  // returns 0 or errno
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifindex;
    return ::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 ? 0 : errno;
  }
  void bindOrFail(int ifindex, const char* what) {
    if (int e = bindTo(ifindex)) {
      errno = e;
      fail(errnoText(what));
    }
  }
  void send(const can_frame& f) {
    ssize_t n = ::write(fd_, &f, sizeof f);
    if (n != static_cast<ssize_t>(sizeof f)) fail(errnoText("write(can_frame)"));
  }

 private:
  int fd_;
};

struct Received {
  can_frame frame{};
  bool hasStamp = false;
  timeval stamp{};
  int flags = 0;
};

// Waits up to timeoutMs for a frame; false on timeout.
bool receive(Socket& s, int timeoutMs, Received* out) {
  pollfd p{s.fd(), POLLIN, 0};
  int r = ::poll(&p, 1, timeoutMs);
  if (r < 0) fail(errnoText("poll"));
  if (r == 0) return false;
  iovec iov{&out->frame, sizeof out->frame};
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timeval)) + 64];
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  msg.msg_control = control;
  msg.msg_controllen = sizeof control;
  ssize_t n = ::recvmsg(s.fd(), &msg, 0);
  if (n < 0) fail(errnoText("recvmsg"));
  if (n != static_cast<ssize_t>(sizeof(can_frame))) fail("recvmsg: short frame of " + std::to_string(n) + " bytes");
  out->flags = msg.msg_flags;
  out->hasStamp = false;
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMP) {
      std::memcpy(&out->stamp, CMSG_DATA(c), sizeof(timeval));
      out->hasStamp = true;
    }
  }
  return true;
}

can_frame makeFrame(canid_t id, uint8_t dlc, uint8_t seed) {
  can_frame f{};
  f.can_id = id;
  f.can_dlc = dlc;
  for (uint8_t i = 0; i < dlc; ++i) f.data[i] = static_cast<uint8_t>(seed + 17 * i);
  return f;
}

std::string idText(canid_t id) {
  char buf[32];
  if (id & CAN_EFF_FLAG)
    std::snprintf(buf, sizeof buf, "0x%08" PRIX32 "(ext)", static_cast<uint32_t>(id & CAN_EFF_MASK));
  else
    std::snprintf(buf, sizeof buf, "0x%03" PRIX32, static_cast<uint32_t>(id & CAN_SFF_MASK));
  return buf;
}

bool sameFrame(const can_frame& a, const can_frame& b) {
  return a.can_id == b.can_id && a.can_dlc == b.can_dlc && std::memcmp(a.data, b.data, a.can_dlc) == 0;
}

double monoUs() {
  timespec t{};
  ::clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<double>(t.tv_sec) * 1e6 + static_cast<double>(t.tv_nsec) / 1e3;
}

double stampUs(const timeval& t) { return static_cast<double>(t.tv_sec) * 1e6 + static_cast<double>(t.tv_usec); }

void expectNothing(Socket& s, int timeoutMs, const char* context) {
  Received r;
  if (receive(s, timeoutMs, &r)) fail(std::string(context) + ": unexpected frame " + idText(r.frame.can_id));
}

int interfaceIndex(const std::string& iface, int* mtu) {
  Socket s;
  const int fd = s.fd();
  ifreq ifr{};
  std::snprintf(ifr.ifr_name, IFNAMSIZ, "%s", iface.c_str());
  if (::ioctl(fd, SIOCGIFINDEX, &ifr) != 0) {
    fail(errnoText(("SIOCGIFINDEX " + iface).c_str()) + " (is the interface created? ip link add dev " + iface +
         " type vcan)");
  }
  int index = ifr.ifr_ifindex;
  if (::ioctl(fd, SIOCGIFHWADDR, &ifr) != 0) fail(errnoText("SIOCGIFHWADDR"));
  if (ifr.ifr_hwaddr.sa_family != ARPHRD_CAN)
    fail(iface + " is not a CAN interface (hardware type " + std::to_string(ifr.ifr_hwaddr.sa_family) + ")");
  if (::ioctl(fd, SIOCGIFFLAGS, &ifr) != 0) fail(errnoText("SIOCGIFFLAGS"));
  if (!(ifr.ifr_flags & IFF_UP)) fail(iface + " is down (ip link set " + iface + " up)");
  if (::ioctl(fd, SIOCGIFMTU, &ifr) != 0) fail(errnoText("SIOCGIFMTU"));
  // Classic CAN controllers have CAN_MTU; vcan defaults to CANFD_MTU (it carries both).
  if (ifr.ifr_mtu != static_cast<int>(CAN_MTU) && ifr.ifr_mtu != static_cast<int>(CANFD_MTU))
    fail(iface + " MTU is " + std::to_string(ifr.ifr_mtu) + ", expected CAN_MTU " + std::to_string(CAN_MTU) +
         " or CANFD_MTU " + std::to_string(CANFD_MTU));
  if (mtu) *mtu = ifr.ifr_mtu;
  return index;
}

struct Options {
  std::string iface = "vcan0";
  int frames = 1000;
  double maxP99Us = 0;  // 0: no limit
  int peer = 0;         // round trips with a --serve process (0: none)
  bool serve = false;
};

constexpr canid_t kRequestId = 0x7E0;
constexpr canid_t kReplyId = 0x7E8;

struct Percentiles {
  double p50, p99, max;
};

Percentiles percentiles(std::vector<double> us) {
  std::sort(us.begin(), us.end());
  auto pct = [&](double p) {
    return us[std::min(us.size() - 1, static_cast<size_t>(p * static_cast<double>(us.size())))];
  };
  return {pct(0.50), pct(0.99), us.back()};
}

volatile sig_atomic_t gStop = 0;
void onSignal(int) { gStop = 1; }

// Echo responder: 0x7E0 -> 0x7E8, same payload, until SIGTERM / SIGINT.
void serve(const Options& opt) {
  struct sigaction sa {};
  sa.sa_handler = onSignal;
  ::sigaction(SIGTERM, &sa, nullptr);
  ::sigaction(SIGINT, &sa, nullptr);
  Socket s;
  s.setFilters({{kRequestId, CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG}});
  int ifindex = 0;
  for (int tries = 0; (ifindex = static_cast<int>(::if_nametoindex(opt.iface.c_str()))) == 0; ++tries) {
    if (tries >= 100) fail("serve: no interface " + opt.iface);
    ::usleep(100000);
  }
  s.bindOrFail(ifindex, "serve: bind");
  std::printf("can_kernel_smoke: serving 0x%03X -> 0x%03X on %s\n", kRequestId, kReplyId, opt.iface.c_str());
  std::fflush(stdout);
  long served = 0;
  while (!gStop) {
    pollfd p{s.fd(), POLLIN, 0};
    int r = ::poll(&p, 1, 100);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) fail(errnoText("serve: poll"));
    if (r == 0) continue;
    can_frame f{};
    if (::read(s.fd(), &f, sizeof f) != static_cast<ssize_t>(sizeof f)) {
      if (errno == EINTR) continue;
      fail(errnoText("serve: read"));
    }
    f.can_id = kReplyId;
    s.send(f);
    ++served;
  }
  std::printf("can_kernel_smoke: responder stopped after %ld replies\n", served);
}

// N request/reply round trips with a --serve process.
void peerCheck(const Options& opt, int ifindex) {
  Socket s;
  s.setFilters({{kReplyId, CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG}});
  s.bindOrFail(ifindex, "peer: bind");
  // Wait for the responder (it may still be starting): one request every 100 ms, 10 s.
  Received r;
  bool up = false;
  for (int i = 0; i < 100 && !up; ++i) {
    s.send(makeFrame(kRequestId, 1, 0xEE));
    up = receive(s, 100, &r);
  }
  if (!up) fail("peer: no reply on 0x7E8 within 10 s (is a 'can_kernel_smoke --serve' process running?)");
  while (receive(s, 50, &r)) {
  }  // late replies to the probes
  std::vector<double> us;
  for (int i = 0; i < opt.peer; ++i) {
    can_frame f = makeFrame(kRequestId, 8, static_cast<uint8_t>(i));
    std::memcpy(f.data, &i, sizeof i);
    const double t0 = monoUs();
    s.send(f);
    if (!receive(s, 1000, &r)) fail("peer: reply " + std::to_string(i) + " lost");
    us.push_back(monoUs() - t0);
    can_frame expect = f;
    expect.can_id = kReplyId;
    if (!sameFrame(r.frame, expect)) fail("peer: reply " + std::to_string(i) + " out of order or corrupted");
  }
  const Percentiles p = percentiles(us);
  std::printf(
      "can_kernel_smoke: round trip with another process over %d requests: p50 %.1f us, p99 %.1f us, "
      "max %.1f us\n",
      opt.peer, p.p50, p.p99, p.max);
}

// 6. Error frames written by a socket, delivered by af_can through the error masks.
void errorFrameCheck(int ifindex) {
  Socket inj, all, busoffOnly, none;
  inj.setFilters({});  // the writer receives nothing itself
  all.setFilters({});  // no data frames: error frames go through the error mask only
  all.setOpt(SOL_CAN_RAW, CAN_RAW_ERR_FILTER, static_cast<can_err_mask_t>(CAN_ERR_MASK),
             "setsockopt(CAN_RAW_ERR_FILTER)");
  busoffOnly.setOpt(SOL_CAN_RAW, CAN_RAW_ERR_FILTER, static_cast<can_err_mask_t>(CAN_ERR_BUSOFF),
                    "setsockopt(CAN_RAW_ERR_FILTER)");
  // `none` keeps the defaults: every data frame, error mask 0.
  for (Socket* s : {&inj, &all, &busoffOnly, &none}) s->bindOrFail(ifindex, "error frames: bind");
  can_frame busoff{};
  busoff.can_id = CAN_ERR_FLAG | CAN_ERR_BUSOFF;
  busoff.can_dlc = CAN_ERR_DLC;
  can_frame passive{};
  passive.can_id = CAN_ERR_FLAG | CAN_ERR_CRTL;
  passive.can_dlc = CAN_ERR_DLC;
  passive.data[1] = CAN_ERR_CRTL_TX_PASSIVE;
  passive.data[6] = 0x80;  // tx error counter 128 (CAN_ERR_CRTL's data[6])
  auto write = [&](const can_frame& f, const char* what) {
    const ssize_t n = ::write(inj.fd(), &f, sizeof f);
    if (n != static_cast<ssize_t>(sizeof f))
      fail(std::string("error frames: writing the ") + what + " error frame was refused (" + errnoText("write") + ")");
  };
  auto expectError = [&](Socket& s, const can_frame& want, const char* who, const char* what) {
    Received r;
    if (!receive(s, 1000, &r))
      fail(std::string("error frames: the ") + who + " socket did not receive the " + what + " error frame within 1 s");
    if (!sameFrame(r.frame, want)) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "can_id 0x%08" PRIX32 " dlc %d data[1] 0x%02X",
                    static_cast<uint32_t>(r.frame.can_id), r.frame.can_dlc, r.frame.data[1]);
      fail(std::string("error frames: the ") + who + " socket got " + buf + " instead of the " + what + " error frame");
    }
  };
  write(busoff, "bus-off");
  expectError(all, busoff, "CAN_ERR_MASK", "bus-off");
  expectError(busoffOnly, busoff, "CAN_ERR_BUSOFF-only", "bus-off");
  write(passive, "error-passive (CAN_ERR_CRTL)");
  expectError(all, passive, "CAN_ERR_MASK", "error-passive");
  // A sentinel data frame: by the time it arrives, any error frame would have too.
  const can_frame sentinel = makeFrame(0x3A5, 2, 0x11);
  inj.send(sentinel);
  Received r;
  if (!receive(busoffOnly, 1000, &r)) fail("error frames: the sentinel data frame did not arrive");
  if (!sameFrame(r.frame, sentinel))
    fail("error frames: the CAN_ERR_BUSOFF-only socket received a frame of another error class (" +
         idText(r.frame.can_id) + ") before the sentinel");
  if (!receive(none, 1000, &r)) fail("error frames: the sentinel data frame did not reach the error-mask-0 socket");
  if (!sameFrame(r.frame, sentinel))
    fail("error frames: a socket with error mask 0 (and an accept-all data filter) received an error frame");
  expectNothing(inj, 100, "error frames: the writer (RECV_OWN_MSGS off)");
  expectNothing(all, 50, "error frames: the CAN_ERR_MASK socket after both error frames");
  std::printf(
      "can_kernel_smoke: error frames OK (written CAN_ERR_BUSOFF and CAN_ERR_CRTL/tx-passive delivered "
      "through CAN_RAW_ERR_FILTER by class, not to error mask 0 nor to the writer)\n");
}

// 2. loopback semantics
void loopbackCheck(int ifindex) {
  Socket tx, rx;
  tx.bindOrFail(ifindex, "bind tx");
  rx.bindOrFail(ifindex, "bind rx");
  int loopback = -1, recvOwn = -1;
  socklen_t len = sizeof loopback;
  if (::getsockopt(tx.fd(), SOL_CAN_RAW, CAN_RAW_LOOPBACK, &loopback, &len) != 0)
    fail(errnoText("getsockopt(LOOPBACK)"));
  len = sizeof recvOwn;
  if (::getsockopt(tx.fd(), SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &recvOwn, &len) != 0)
    fail(errnoText("getsockopt(RECV_OWN_MSGS)"));
  if (loopback != 1 || recvOwn != 0)
    fail("default CAN_RAW_LOOPBACK=" + std::to_string(loopback) + " CAN_RAW_RECV_OWN_MSGS=" + std::to_string(recvOwn) +
         ", expected 1 and 0");

  const can_frame f = makeFrame(0x321, 4, 0x40);
  tx.send(f);
  Received r;
  if (!receive(rx, 1000, &r)) fail("loopback: the other socket did not receive frame 0x321 within 1 s");
  if (!sameFrame(r.frame, f)) fail("loopback: received frame differs from the sent one");
  if (r.flags & MSG_CONFIRM) fail("loopback: frame from another socket flagged MSG_CONFIRM");
  expectNothing(tx, 100, "RECV_OWN_MSGS off: sender");

  tx.setOpt(SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, 1, "setsockopt(RECV_OWN_MSGS)");
  tx.send(f);
  if (!receive(tx, 1000, &r)) fail("RECV_OWN_MSGS on: the sender did not get its own frame");
  if (!(r.flags & MSG_CONFIRM)) fail("RECV_OWN_MSGS on: own frame not flagged MSG_CONFIRM");
  if (!receive(rx, 1000, &r) || !sameFrame(r.frame, f)) fail("RECV_OWN_MSGS on: the other socket lost the frame");

  Socket quiet;
  quiet.bindOrFail(ifindex, "bind quiet");
  quiet.setOpt(SOL_CAN_RAW, CAN_RAW_LOOPBACK, 0, "setsockopt(LOOPBACK)");
  quiet.send(f);
  expectNothing(rx, 100, "LOOPBACK off: other socket");
  std::printf(
      "can_kernel_smoke: loopback semantics OK (LOOPBACK=1, RECV_OWN_MSGS=0 defaults; MSG_CONFIRM on own frames)\n");
}

// 3. filters, order, timestamps, DLC
void filterCheck(int ifindex) {
  Socket tx, rx;
  tx.bindOrFail(ifindex, "bind tx");
  // Standard ids 0x100..0x1FF (EFF flag in the mask: extended frames do not match),
  // and exactly the extended id 0x12345678.
  rx.setFilters({{0x100, 0x700 | CAN_EFF_FLAG | CAN_RTR_FLAG},
                 {0x12345678 | CAN_EFF_FLAG, CAN_EFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG}});
  rx.setOpt(SOL_SOCKET, SO_TIMESTAMP, 1, "setsockopt(SO_TIMESTAMP)");
  rx.bindOrFail(ifindex, "bind rx");

  struct Sent {
    can_frame f;
    bool wanted;
  };
  const std::vector<Sent> sent = {
      {makeFrame(0x123, 8, 0x01), true},
      {makeFrame(0x200, 8, 0x02), false},                 // standard id outside the mask
      {makeFrame(0x1FF, 0, 0x03), true},                  // DLC 0
      {makeFrame(0x123 | CAN_EFF_FLAG, 8, 0x04), false},  // extended id 0x123: not the standard 0x123
      {makeFrame(0x12345678 | CAN_EFF_FLAG, 8, 0x05), true},
      {makeFrame(0x12345679 | CAN_EFF_FLAG, 3, 0x06), false},
      {makeFrame(0x100, 1, 0x07), true},
      {makeFrame(0x12345678 | CAN_EFF_FLAG, 0, 0x08), true},  // extended, DLC 0
      {makeFrame(0x7FF, 8, 0x09), false},
      {makeFrame(0x1AA, 8, 0x0A), true},  // last: sentinel
  };
  timeval before{};
  ::gettimeofday(&before, nullptr);
  for (const Sent& s : sent) tx.send(s.f);

  double lastStamp = 0;
  int count = 0;
  for (const Sent& s : sent) {
    if (!s.wanted) continue;
    Received r;
    if (!receive(rx, 1000, &r)) fail("filters: frame " + idText(s.f.can_id) + " did not arrive within 1 s");
    if (!sameFrame(r.frame, s.f))
      fail("filters/order: expected " + idText(s.f.can_id) + " dlc " + std::to_string(s.f.can_dlc) + ", got " +
           idText(r.frame.can_id) + " dlc " + std::to_string(r.frame.can_dlc));
    if (!r.hasStamp) fail("SO_TIMESTAMP: frame " + idText(r.frame.can_id) + " has no timestamp");
    const double st = stampUs(r.stamp);
    if (st < lastStamp) fail("SO_TIMESTAMP: timestamps go backwards");
    if (std::abs(st - stampUs(before)) > 5e6) fail("SO_TIMESTAMP: timestamp more than 5 s from the wall clock");
    lastStamp = st;
    ++count;
  }
  expectNothing(rx, 200, "filters: after the sentinel");

  can_frame bad = makeFrame(0x123, 8, 0);
  bad.can_dlc = 9;
  if (::write(tx.fd(), &bad, sizeof bad) >= 0 || errno != EINVAL)
    fail("a frame with DLC 9 was not refused with EINVAL (" + errnoText("write") + ")");
  std::printf(
      "can_kernel_smoke: filters OK (%d of %zu frames passed, in order, SO_TIMESTAMP present and monotonic, "
      "DLC 9 refused)\n",
      count, sent.size());
}

// 4. latency
void latencyCheck(const Options& opt, int ifindex) {
  Socket tx, rx;
  tx.bindOrFail(ifindex, "bind tx");
  rx.bindOrFail(ifindex, "bind rx");
  std::vector<double> us;
  us.reserve(static_cast<size_t>(opt.frames));
  for (int i = 0; i < opt.frames; ++i) {
    can_frame f = makeFrame(0x080 + (i & 0x3F), 8, static_cast<uint8_t>(i));
    std::memcpy(f.data, &i, sizeof i);
    const double t0 = monoUs();
    tx.send(f);
    Received r;
    if (!receive(rx, 1000, &r)) fail("latency: frame " + std::to_string(i) + " lost");
    const double t1 = monoUs();
    if (!sameFrame(r.frame, f)) fail("latency: frame " + std::to_string(i) + " out of order or corrupted");
    us.push_back(t1 - t0);
  }
  const Percentiles pc = percentiles(us);
  const double p50 = pc.p50, p99 = pc.p99, mx = pc.max;
  std::printf("can_kernel_smoke: latency send->receive over %d frames: p50 %.1f us, p99 %.1f us, max %.1f us\n",
              opt.frames, p50, p99, mx);
  if (opt.maxP99Us > 0 && p99 > opt.maxP99Us)
    fail("latency p99 " + std::to_string(p99) + " us above the limit " + std::to_string(opt.maxP99Us) + " us");
}

// 5. nonexistent interface
void missingInterfaceCheck() {
  Socket s;
  ifreq ifr{};
  std::snprintf(ifr.ifr_name, IFNAMSIZ, "%s", "nosuchcan9");
  if (::ioctl(s.fd(), SIOCGIFINDEX, &ifr) == 0 || errno != ENODEV)
    fail("SIOCGIFINDEX of a nonexistent interface did not fail with ENODEV (" + errnoText("ioctl") + ")");
  if (::if_nametoindex("nosuchcan9") != 0 || errno != ENODEV)
    fail("if_nametoindex of a nonexistent interface did not fail with ENODEV");
  int e = s.bindTo(4242);  // an ifindex no interface has in the guest
  if (e != ENODEV) {
    errno = e;
    fail("bind() to a nonexistent ifindex did not fail with ENODEV (" + errnoText("bind") + ")");
  }
  std::printf("can_kernel_smoke: nonexistent interface -> ENODEV OK\n");
}

void run(const Options& opt) {
  int mtu = 0;
  const int ifindex = interfaceIndex(opt.iface, &mtu);
  std::printf("can_kernel_smoke: %s ifindex %d, ARPHRD_CAN, up, MTU %d (%s)\n", opt.iface.c_str(), ifindex, mtu,
              mtu == static_cast<int>(CANFD_MTU) ? "CAN FD capable" : "classic CAN");
  loopbackCheck(ifindex);
  filterCheck(ifindex);
  latencyCheck(opt, ifindex);
  missingInterfaceCheck();
  errorFrameCheck(ifindex);
  if (opt.peer > 0) peerCheck(opt, ifindex);
}

int usage(const char* argv0, int code) {
  std::fprintf(code ? stderr : stdout,
               "usage: %s [--iface NAME (vcan0)] [--frames N (1000)] [--max-p99-us US] [--peer N]\n"
               "       %s --serve [--iface NAME]\n",
               argv0, argv0);
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(usage(argv[0], 2));
      }
      return argv[++i];
    };
    if (a == "--iface")
      opt.iface = value();
    else if (a == "--frames")
      opt.frames = std::max(1, std::atoi(value().c_str()));
    else if (a == "--max-p99-us")
      opt.maxP99Us = std::atof(value().c_str());
    else if (a == "--peer")
      opt.peer = std::max(0, std::atoi(value().c_str()));
    else if (a == "--serve")
      opt.serve = true;
    else if (a == "-h" || a == "--help")
      return usage(argv[0], 0);
    else {
      std::fprintf(stderr, "unknown argument '%s'\n", a.c_str());
      return usage(argv[0], 2);
    }
  }
  if (opt.iface.size() >= IFNAMSIZ) {
    std::fprintf(stderr, "interface name too long\n");
    return 2;
  }
  try {
    if (opt.serve) {
      serve(opt);
      return 0;
    }
    run(opt);
  } catch (const Failure& f) {
    std::printf("CAN_KERNEL_SMOKE FAIL: %s\n", f.what.c_str());
    std::fflush(stdout);
    return 1;
  }
  std::printf("CAN_KERNEL_SMOKE OK\n");
  std::fflush(stdout);
  return 0;
}
