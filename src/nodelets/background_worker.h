// A job run on a thread of its own, on the cores' idle time, whenever a stage asks for it.
#pragma once

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

namespace aloam_nodelet
{
/// Runs `job` on its own thread each time request() is called, or once a deadline given to requestBy()
/// has passed (requests made while it runs coalesce into one more run). The thread runs under
/// SCHED_IDLE: the work a stage does after publishing (indexing for the next sweep, updating the map)
/// takes the cores only when no other thread wants them, so it never delays the delivery of the result
/// just published nor the next stage. The stage must be ready to do the job itself when it needs the
/// result and the worker has not got to it (a fully loaded machine).
class BackgroundWorker
{
public:
  explicit BackgroundWorker(std::function<void()> job) : job_(std::move(job))
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

  /// Runs the job now.
  void request()
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      pending_ = true;
    }
    cv_.notify_one();
  }

  /// Runs the job at `deadline`, or earlier if request() comes first.
  void requestBy(std::chrono::steady_clock::time_point deadline)
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      deadline_ = deadline;
    }
    cv_.notify_one();
  }

private:
  static void lowerPriority()
  {
    // Only this thread. Lowering a thread's priority needs no privilege; where SCHED_IDLE is refused,
    // nice 19 (the lowest priority) serves nearly as well.
    sched_param param{};
    param.sched_priority = 0;
    if (pthread_setschedparam(pthread_self(), SCHED_IDLE, &param) != 0)
    {
      setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 19);
    }
  }

  void run()
  {
    lowerPriority();
    std::unique_lock<std::mutex> lock(mutex_);
    while (true)
    {
      if (deadline_)
      {
        const auto until = *deadline_;
        cv_.wait_until(lock, until, [this, until] { return stop_ || pending_ || deadline_ != until; });
      }
      else
      {
        cv_.wait(lock, [this] { return stop_ || pending_ || deadline_; });
      }
      if (stop_)
      {
        return;
      }
      if (!pending_ && !(deadline_ && std::chrono::steady_clock::now() >= *deadline_))
      {
        continue;  // a deadline was set or moved: wait for it
      }
      pending_ = false;
      deadline_.reset();
      lock.unlock();
      job_();
      lock.lock();
    }
  }

  std::function<void()> job_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool pending_ = false;
  std::optional<std::chrono::steady_clock::time_point> deadline_;
  bool stop_ = false;
  std::thread thread_;  // last: starts once everything above is ready
};

}  // namespace aloam_nodelet
