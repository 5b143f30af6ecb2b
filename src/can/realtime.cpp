// Real-time scheduling of the control threads (see realtime.h).
#include "massage_cell/can/realtime.h"

#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string>
#include <system_error>

namespace massage_cell::can {

namespace {

std::string limitText(int resource, const char* unit) {
  rlimit l{};
  if (getrlimit(resource, &l) != 0) return "unknown";
  if (l.rlim_cur == RLIM_INFINITY) return "unlimited";
  return std::to_string(l.rlim_cur) + unit;
}

}  // namespace

std::string RealtimeStatus::describe() const {
  std::string s = priority > 0 ? "SCHED_FIFO priority " + std::to_string(priority) : "normal (SCHED_OTHER)";
  if (memory_locked) s += ", memory locked";
  if (!error.empty()) s += ": " + error;
  return s;
}

std::string setRealtimePriority(pthread_t thread, int priority) {
  const std::string what = "SCHED_FIFO priority " + std::to_string(priority);
  if (priority < 1 || priority > 99) return what + " refused: the priority must be 1..99";
  sched_param param{};
  param.sched_priority = priority;
  const int rc = pthread_setschedparam(thread, SCHED_FIFO, &param);
  if (rc == 0) return "";
  if (rc == EPERM) {
    return what + " refused (" + std::strerror(rc) +
           "): the process needs CAP_SYS_NICE or an rtprio limit >= " + std::to_string(priority) + " (now " +
           limitText(RLIMIT_RTPRIO, "") + "): run `ulimit -r " + std::to_string(priority) +
           "` before starting it, or add `<user> - rtprio 99` to /etc/security/limits.conf (log in again), or "
           "`setcap cap_sys_nice+ep <executable>`; in a container, --cap-add=SYS_NICE / --ulimit rtprio=99";
  }
  return what + " refused: pthread_setschedparam: " + std::strerror(rc);
}

std::string lockMemory() {
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) return "";
  const int err = errno;
  return std::string("mlockall refused (") + std::strerror(err) + "): the memlock limit (now " +
         limitText(RLIMIT_MEMLOCK, " bytes") +
         ") is below the process's size or CAP_IPC_LOCK is missing: run `ulimit -l unlimited` before starting it, or "
         "add `<user> - memlock unlimited` to /etc/security/limits.conf; memory stays pageable";
}

RecursivePiMutex::RecursivePiMutex() {
  pthread_mutexattr_t attr;
  if (pthread_mutexattr_init(&attr) != 0) throw std::runtime_error("RecursivePiMutex: pthread_mutexattr_init failed");
  pthread_mutexattr_settype(&attr, PTHREAD_MUTEX_RECURSIVE);
  inherit_ = pthread_mutexattr_setprotocol(&attr, PTHREAD_PRIO_INHERIT) == 0 && pthread_mutex_init(&mutex_, &attr) == 0;
  if (!inherit_) {
    pthread_mutexattr_setprotocol(&attr, PTHREAD_PRIO_NONE);
    const int e = pthread_mutex_init(&mutex_, &attr);
    pthread_mutexattr_destroy(&attr);
    if (e != 0) throw std::runtime_error(std::string("RecursivePiMutex: pthread_mutex_init: ") + std::strerror(e));
    return;
  }
  pthread_mutexattr_destroy(&attr);
}

RecursivePiMutex::~RecursivePiMutex() { pthread_mutex_destroy(&mutex_); }

void RecursivePiMutex::lock() {
  const int e = pthread_mutex_lock(&mutex_);
  if (e != 0) throw std::system_error(e, std::generic_category(), "RecursivePiMutex::lock");
}

bool RecursivePiMutex::try_lock() { return pthread_mutex_trylock(&mutex_) == 0; }

void RecursivePiMutex::unlock() { pthread_mutex_unlock(&mutex_); }

int realtimePriority(pthread_t thread) {
  int policy = 0;
  sched_param param{};
  if (pthread_getschedparam(thread, &policy, &param) != 0) return 0;
  return policy == SCHED_FIFO || policy == SCHED_RR ? param.sched_priority : 0;
}

}  // namespace massage_cell::can
