// A flag one thread sets and others wait for (the thread tests' hand-shakes).
#pragma once

#include <condition_variable>
#include <mutex>

namespace aloam_test
{
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
}  // namespace aloam_test
