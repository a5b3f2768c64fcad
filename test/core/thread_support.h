// What the thread tests share: a hand-shake flag, the calling thread's id and the count of the process's
// threads.
#pragma once

#include <sys/syscall.h>
#include <sys/types.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <filesystem>
#include <mutex>
#include <thread>

namespace aloam_test
{
/// The calling thread's kernel id (what /proc/self/task lists and sched_getaffinity takes).
inline pid_t threadId()
{
  return static_cast<pid_t>(syscall(SYS_gettid));
}

/// A flag one thread sets and others wait for.
class Latch
{
public:
  void open()
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      open_ = true;
    }
    cv_.notify_all();
  }
  void wait()
  {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait(lock, [this] { return open_; });
  }
  bool isOpen()
  {
    std::lock_guard<std::mutex> lock(mutex_);
    return open_;
  }

private:
  std::mutex mutex_;
  std::condition_variable cv_;
  bool open_ = false;
};

/// The threads of this process now (/proc/self/task).
inline std::size_t threadsOfThisProcess()
{
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator("/proc/self/task"))
  {
    ++n;
  }
  return n;
}

// A joined thread may still be listed for a moment: the kernel wakes the joiner before it unlists the
// thread, and on a loaded machine the exiting thread can be preempted in between.

/// The thread count once it has held still for 50 ms: threads joined just before are gone from it.
inline std::size_t settledThreadCount()
{
  std::size_t count = threadsOfThisProcess();
  for (int still = 0; still < 50; ++still)
  {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    const std::size_t now = threadsOfThisProcess();
    if (now != count)
    {
      count = now;
      still = -1;
    }
  }
  return count;
}

/// Polls until this process has `count` threads; false if it still has another count after `timeout_s`.
inline bool threadsDropTo(std::size_t count, double timeout_s = 60.0)
{
  const auto give_up =
      std::chrono::steady_clock::now() +
      std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(timeout_s));
  while (threadsOfThisProcess() != count && std::chrono::steady_clock::now() < give_up)
  {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return threadsOfThisProcess() == count;
}
}  // namespace aloam_test
