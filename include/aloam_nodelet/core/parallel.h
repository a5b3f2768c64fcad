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
/// A helper thread that runs one task at a time for the thread that owns it. After a task it stays
/// awake for a moment: the parallel regions of one sweep follow each other within milliseconds, and
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

/// The calling thread's helpers (created on first use, stopped when the thread ends).
inline std::vector<std::unique_ptr<Helper>>& helpersOfThisThread(std::size_t count)
{
  thread_local std::vector<std::unique_ptr<Helper>> helpers;
  while (helpers.size() < count)
  {
    helpers.push_back(std::make_unique<Helper>());
  }
  return helpers;
}
}  // namespace detail

/// Calls body(begin, end, part) for `parts` contiguous, nearly equal chunks of [0, count), part 0 on the
/// calling thread and the others on its helper threads, and returns when all are done. With one part,
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
  auto& helpers = detail::helpersOfThisThread(static_cast<std::size_t>(parts - 1));
  const auto bound = [&](int part) { return static_cast<int>(static_cast<long long>(count) * part / parts); };
  for (int part = 1; part < parts; ++part)
  {
    helpers[part - 1]->start([&body, &bound, part] { body(bound(part), bound(part + 1), part); });
  }
  body(0, bound(1), 0);
  for (int part = 1; part < parts; ++part)
  {
    helpers[part - 1]->wait();
  }
}

}  // namespace aloam
