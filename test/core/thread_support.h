// What the thread tests share: a hand-shake flag and the count of the process's threads.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <filesystem>
#include <mutex>

namespace aloam_test
{
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
}  // namespace aloam_test
