// A one-item slot and the worker thread that processes its newest item: the
// stereo nodelets' input side (a synchroniser callback puts each pair in,
// replacing and counting as dropped a pair the worker has not taken yet; the
// worker hands the newest one to the handler, so callbacks never wait for
// the processing). ROS-free; header-only.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

namespace massage_cell::camera {

template <typename T>
class LatestWorker {
 public:
  using Handler = std::function<void(T&)>;
  struct Counts {
    std::uint64_t received = 0;  ///< items put in
    std::uint64_t dropped = 0;   ///< replaced in the slot before the worker took them
  };

  /// Starts the worker, which calls `handler` (it must not throw) with each item it takes.
  explicit LatestWorker(Handler handler) : handler_(std::move(handler)), worker_([this] { loop(); }) {}
  ~LatestWorker() { stop(); }
  LatestWorker(const LatestWorker&) = delete;
  LatestWorker& operator=(const LatestWorker&) = delete;

  /// Puts `item` in the slot (thread-safe). Ignored after stop().
  void put(T item) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stopping_) return;
      ++counts_.received;
      if (slot_) ++counts_.dropped;  // the worker is busy and never took the previous item
      slot_ = std::move(item);
    }
    cv_.notify_one();
  }

  /// Ends the worker once it has finished the item it is processing (waits
  /// for it; an item still in the slot is not processed). Idempotent; not
  /// from the handler.
  void stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    cv_.notify_all();
    std::lock_guard<std::mutex> join_lock(join_mutex_);
    if (worker_.joinable()) worker_.join();
  }

  Counts counts() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return counts_;
  }

 private:
  void loop() {
    while (true) {
      T item;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        cv_.wait(lock, [this] { return stopping_ || slot_.has_value(); });
        if (stopping_) return;
        item = std::move(*slot_);
        slot_.reset();
      }
      handler_(item);
    }
  }

  Handler handler_;
  mutable std::mutex mutex_;
  std::mutex join_mutex_;  ///< stop() from several threads joins once
  std::condition_variable cv_;
  std::optional<T> slot_;
  bool stopping_ = false;
  Counts counts_;
  std::thread worker_;  ///< last: started once everything above exists
};

}  // namespace massage_cell::camera
