// A job run on a thread of its own, at a lower scheduling priority, whenever a stage asks for it.
#pragma once

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>

namespace aloam_nodelet
{
/// Runs `job` on its own thread each time request() is called (requests made while it runs coalesce into
/// one more run). The thread is niced so that the work a stage does after publishing (indexing for the
/// next sweep) yields the cores to the next stage's latency path rather than competing with it.
class BackgroundWorker
{
public:
  BackgroundWorker(std::function<void()> job, int nice_increment) : job_(std::move(job)), nice_(nice_increment)
  {
    thread_ = std::thread(&BackgroundWorker::run, this);
  }

  /// Waits for a running job, then stops.
  ~BackgroundWorker()
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }

  BackgroundWorker(const BackgroundWorker&) = delete;
  BackgroundWorker& operator=(const BackgroundWorker&) = delete;

  void request()
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      pending_ = true;
    }
    cv_.notify_one();
  }

private:
  void run()
  {
    // Only this thread: on Linux the nice value belongs to the thread. Lowering priority needs no privilege.
    setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), nice_);
    std::unique_lock<std::mutex> lock(mutex_);
    while (true)
    {
      cv_.wait(lock, [this] { return stop_ || pending_; });
      if (stop_)
      {
        return;
      }
      pending_ = false;
      lock.unlock();
      job_();
      lock.lock();
    }
  }

  std::function<void()> job_;
  int nice_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool pending_ = false;
  bool stop_ = false;
  std::thread thread_;  // last: starts once everything above is ready
};

}  // namespace aloam_nodelet
