// Splitting a loop over a few threads (the correspondence searches, the rings of a sweep).
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace aloam
{
namespace detail
{
/// A helper thread that runs one task at a time for the thread its team is lent to. After a task it
/// stays awake for a moment: the parallel regions of one sweep follow each other within milliseconds, and
/// waking an idle core costs more than the spin (measured at the sensor rate on a 2-vCPU machine).
class Helper
{
public:
  Helper() : thread_([this] { loop(); }) {}
  ~Helper()
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    cv_.notify_one();
    thread_.join();
  }
  Helper(const Helper&) = delete;
  Helper& operator=(const Helper&) = delete;

  void start(std::function<void()> task)
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      task_ = std::move(task);
      busy_.store(true, std::memory_order_release);
    }
    cv_.notify_one();
  }

  void wait() const
  {
    while (busy_.load(std::memory_order_acquire))
    {
      std::this_thread::yield();
    }
  }

private:
  static constexpr std::chrono::microseconds kStayAwake{ 2000 };

  void loop()
  {
    while (true)
    {
      const auto until = std::chrono::steady_clock::now() + kStayAwake;
      while (!busy_.load(std::memory_order_acquire) && !stop_.load() && std::chrono::steady_clock::now() < until)
      {
        std::this_thread::yield();
      }
      std::function<void()> task;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        cv_.wait(lock, [this] { return stop_.load() || busy_.load(std::memory_order_acquire); });
        if (stop_)
        {
          return;
        }
        task = task_;
      }
      task();
      busy_.store(false, std::memory_order_release);
    }
  }

  std::mutex mutex_;
  std::condition_variable cv_;
  std::function<void()> task_;
  std::atomic<bool> busy_{ false };
  std::atomic<bool> stop_{ false };
  std::thread thread_;  // last: starts once everything above is ready
};

/// Helper threads for one parallel region at a time.
using HelperTeam = std::vector<std::unique_ptr<Helper>>;

/// Lends a team with at least `count` helpers. Teams are shared by every thread of the process (the
/// stages of a pipeline run one after another on different threads, and the team the last region gave
/// back is still awake when the next stage starts); a team is created when all are lent out, so
/// concurrent regions (two pipelines, a background job) never wait for each other.
HelperTeam* lendTeam(std::size_t count);
/// Gives a team back; the most recently returned is lent next.
void returnTeam(HelperTeam* team);
}  // namespace detail

/// Calls body(begin, end, part) for `parts` contiguous, nearly equal chunks of [0, count), part 0 on the
/// calling thread and the others on helper threads, and returns when all are done. With one part,
/// or too little work to be worth sharing, everything runs here. Chunks write to disjoint outputs, so
/// results do not depend on the number of parts.
template <typename Body>
void parallelChunks(int count, int parts, int min_chunk, Body&& body)
{
  parts = std::clamp(parts, 1, std::max(1, count / std::max(1, min_chunk)));
  if (parts <= 1)
  {
    body(0, count, 0);
    return;
  }
  const auto bound = [&](int part) { return static_cast<int>(static_cast<long long>(count) * part / parts); };
  // Waits for the helpers and gives the team back however this returns (also if body throws here).
  struct Lease
  {
    detail::HelperTeam* team;
    int started = 0;
    ~Lease()
    {
      for (int i = 0; i < started; ++i)
      {
        (*team)[i]->wait();
      }
      detail::returnTeam(team);
    }
  } lease{ detail::lendTeam(static_cast<std::size_t>(parts - 1)) };
  for (int part = 1; part < parts; ++part)
  {
    (*lease.team)[part - 1]->start([&body, &bound, part] { body(bound(part), bound(part + 1), part); });
    ++lease.started;
  }
  body(0, bound(1), 0);
}

}  // namespace aloam
