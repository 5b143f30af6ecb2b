// Real-time scheduling of the control threads (the master's SYNC / poll
// thread, the simulated drives' threads): SCHED_FIFO at a priority through
// pthread_setschedparam, and optionally mlockall(MCL_CURRENT | MCL_FUTURE).
// A refusal (no CAP_SYS_NICE and an rtprio limit below the priority, a
// container without a real-time budget, a memlock limit too small) is
// returned as text naming the problem and the fix, never thrown: the caller
// reports it once and goes on with normal scheduling.
#pragma once

#include <pthread.h>

#include <string>

namespace massage_cell::can {

/// What the control threads should run with.
struct RealtimeOptions {
  int priority = 0;          ///< SCHED_FIFO priority 1..99; 0: normal scheduling (SCHED_OTHER)
  bool lock_memory = false;  ///< mlockall(MCL_CURRENT | MCL_FUTURE): no page faults in the cycle
};

/// What they got.
struct RealtimeStatus {
  int requested = 0;  ///< the priority asked for (0: normal scheduling)
  int priority = 0;   ///< the SCHED_FIFO priority in effect (0: normal scheduling)
  bool lock_requested = false;
  bool memory_locked = false;
  std::string error;  ///< every refusal, with its fix; empty when all is as asked
  bool active() const { return priority > 0; }
  /// "SCHED_FIFO priority 50", "normal (SCHED_OTHER)", or
  /// "normal (SCHED_OTHER): SCHED_FIFO priority 50 refused: ..."; plus ", memory locked".
  std::string describe() const;
};

/// Puts `thread` under SCHED_FIFO at `priority` (1..99). Empty on success,
/// else why not and how to allow it (the thread keeps its scheduling).
std::string setRealtimePriority(pthread_t thread, int priority);
/// mlockall(MCL_CURRENT | MCL_FUTURE). Empty on success, else why not and the fix.
std::string lockMemory();
/// The SCHED_FIFO / SCHED_RR priority of `thread`; 0 under any other policy.
int realtimePriority(pthread_t thread);
/// A recursive mutex with priority inheritance (PTHREAD_PRIO_INHERIT): a
/// normally scheduled thread holding it (a ROS callback reading the status)
/// runs at the priority of a SCHED_FIFO thread waiting for it until it lets
/// go, instead of making that thread wait behind every other process. Where
/// the platform refuses the protocol it is a plain recursive mutex
/// (priorityInheritance() says which). Lockable: std::lock_guard,
/// std::unique_lock, std::condition_variable_any.
class RecursivePiMutex {
 public:
  RecursivePiMutex();
  ~RecursivePiMutex();
  RecursivePiMutex(const RecursivePiMutex&) = delete;
  RecursivePiMutex& operator=(const RecursivePiMutex&) = delete;
  void lock();
  bool try_lock();
  void unlock();
  bool priorityInheritance() const { return inherit_; }
  pthread_mutex_t* native_handle() { return &mutex_; }

 private:
  pthread_mutex_t mutex_;
  bool inherit_ = false;
};

}  // namespace massage_cell::can
