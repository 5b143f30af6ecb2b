// camera::LatestWorker: the newest item wins, counts add up, stop() waits
// and is idempotent; hammered from several threads (also run under TSan:
// docs/safety.md).
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <set>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "massage_cell/camera/latest_worker.h"

using massage_cell::camera::LatestWorker;
using namespace std::chrono_literals;

namespace {

// Blocks the handler until opened.
class Gate {
 public:
  void open() {
    {
      std::lock_guard<std::mutex> lock(m_);
      open_ = true;
    }
    cv_.notify_all();
  }
  void pass() {
    std::unique_lock<std::mutex> lock(m_);
    cv_.wait(lock, [this] { return open_; });
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  bool open_ = false;
};

template <typename Pred>
bool waitFor(Pred pred, std::chrono::milliseconds limit = 5000ms) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (!pred()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

TEST(LatestWorker, TheNewestItemWinsWhileTheHandlerIsBusy) {
  Gate gate;
  std::mutex m;
  std::vector<int> seen;
  std::atomic<bool> first_started{false};
  LatestWorker<int> worker([&](int& item) {
    if (item == 1) {
      first_started = true;
      gate.pass();
    }
    std::lock_guard<std::mutex> lock(m);
    seen.push_back(item);
  });
  worker.put(1);
  ASSERT_TRUE(waitFor([&] { return first_started.load(); }));
  for (int i = 2; i <= 4; ++i) worker.put(i);  // 2 and 3 are replaced before the worker is free
  gate.open();
  ASSERT_TRUE(waitFor([&] {
    std::lock_guard<std::mutex> lock(m);
    return seen.size() == 2;
  }));
  worker.stop();
  EXPECT_EQ(seen, (std::vector<int>{1, 4}));
  EXPECT_EQ(worker.counts().received, 4u);
  EXPECT_EQ(worker.counts().dropped, 2u);
}

TEST(LatestWorker, ManyProducersCountsAddUpAndEachProducersItemsStayInOrder) {
  constexpr int kProducers = 4, kItems = 5000;
  std::vector<std::vector<int>> processed(kProducers);  // the handler's thread only
  std::atomic<int> handled{0};
  LatestWorker<std::pair<int, int>> worker([&](std::pair<int, int>& item) {
    processed[item.first].push_back(item.second);
    ++handled;
  });
  std::vector<std::thread> producers;
  for (int p = 0; p < kProducers; ++p) {
    producers.emplace_back([&worker, p] {
      for (int i = 0; i < kItems; ++i) {
        worker.put({p, i});
        if (i % 64 == 0) std::this_thread::yield();
      }
    });
  }
  for (auto& t : producers) t.join();
  // The last item left in the slot is taken unless stop() comes first: wait for the worker to drain it.
  ASSERT_TRUE(waitFor([&] {
    const auto c = worker.counts();
    return static_cast<std::uint64_t>(handled.load()) + c.dropped == c.received;
  }));
  worker.stop();
  const auto counts = worker.counts();
  EXPECT_EQ(counts.received, static_cast<std::uint64_t>(kProducers * kItems));
  EXPECT_EQ(static_cast<std::uint64_t>(handled.load()) + counts.dropped, counts.received);
  EXPECT_GT(handled.load(), 0);
  for (const auto& items : processed) {
    for (std::size_t i = 1; i < items.size(); ++i)
      ASSERT_LT(items[i - 1], items[i]) << "a producer's items went backwards";
  }
}

TEST(LatestWorker, StopWaitsForTheItemBeingProcessedAndIgnoresLaterOnes) {
  Gate gate;
  std::atomic<bool> started{false}, finished{false};
  std::atomic<int> calls{0};
  LatestWorker<int> worker([&](int&) {
    ++calls;
    started = true;
    gate.pass();
    std::this_thread::sleep_for(20ms);
    finished = true;
  });
  worker.put(1);
  ASSERT_TRUE(waitFor([&] { return started.load(); }));
  worker.put(2);  // still in the slot when stop() comes: never processed
  std::thread opener([&] {
    std::this_thread::sleep_for(20ms);
    gate.open();
  });
  std::thread other_stopper([&] { worker.stop(); });
  worker.stop();
  EXPECT_TRUE(finished.load()) << "stop() returned while the handler was still running";
  other_stopper.join();
  opener.join();
  worker.put(3);
  worker.stop();
  EXPECT_EQ(calls.load(), 1);
  EXPECT_EQ(worker.counts().received, 2u) << "an item put after stop() was counted";
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
