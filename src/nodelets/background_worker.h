// A job run on a thread of its own whenever a stage asks for it, started only when a core is idle.
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
/// Runs `job` on its own thread after request(), or once a deadline given to requestBy() has passed
/// (requests made while it runs coalesce into one more run). For the work a stage does after publishing
/// (indexing for the next sweep, updating the map): a job starts only when a core is idle, so it delays
/// neither the delivery of the result just published nor the next stage, and then runs at normal
/// priority, so that a stage waiting for the job's lock never waits on a starved thread. The gate is a
/// second thread under SCHED_IDLE, which the kernel runs only when nothing else wants a core. On a
/// machine with no idle time nothing starts; the stage must then do the job itself when it needs it.
class BackgroundWorker
{
public:
  explicit BackgroundWorker(std::function<void()> job) : job_(std::move(job))
  {
    runner_ = std::thread(&BackgroundWorker::runLoop, this);
    starter_ = std::thread(&BackgroundWorker::startLoop, this);
  }

  /// Waits for a running job, then stops.
  ~BackgroundWorker()
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    start_cv_.notify_all();
    run_cv_.notify_all();
    starter_.join();
    runner_.join();
  }

  BackgroundWorker(const BackgroundWorker&) = delete;
  BackgroundWorker& operator=(const BackgroundWorker&) = delete;

  /// Runs the job as soon as a core is idle.
  void request()
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      pending_ = true;
    }
    start_cv_.notify_one();
  }

  /// Runs the job once `deadline` has passed and a core is idle, or earlier if request() comes first.
  void requestBy(std::chrono::steady_clock::time_point deadline)
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      deadline_ = deadline;
    }
    start_cv_.notify_one();
  }

private:
  // The gate: runs only on idle time (lowering a thread's priority needs no privilege; where SCHED_IDLE
  // is refused, nice 19 serves nearly as well) and hands due requests to the runner.
  void startLoop()
  {
    sched_param param{};
    param.sched_priority = 0;
    if (pthread_setschedparam(pthread_self(), SCHED_IDLE, &param) != 0)
    {
      setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 19);
    }
    std::unique_lock<std::mutex> lock(mutex_);
    while (true)
    {
      if (deadline_)
      {
        const auto until = *deadline_;
        start_cv_.wait_until(lock, until, [this, until] { return stop_ || pending_ || deadline_ != until; });
      }
      else
      {
        start_cv_.wait(lock, [this] { return stop_ || pending_ || deadline_; });
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
      due_ = true;
      run_cv_.notify_one();
    }
  }

  // Runs the job at the priority the stage's threads have.
  void runLoop()
  {
    std::unique_lock<std::mutex> lock(mutex_);
    while (true)
    {
      run_cv_.wait(lock, [this] { return stop_ || due_; });
      if (stop_)
      {
        return;
      }
      due_ = false;
      lock.unlock();
      job_();
      lock.lock();
    }
  }

  std::function<void()> job_;
  std::mutex mutex_;
  std::condition_variable start_cv_, run_cv_;
  bool pending_ = false;  // requested, not yet handed to the runner
  std::optional<std::chrono::steady_clock::time_point> deadline_;
  bool due_ = false;  // handed to the runner, not yet started
  bool stop_ = false;
  std::thread runner_, starter_;  // last: start once everything above is ready
};

}  // namespace aloam_nodelet
