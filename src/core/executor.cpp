#include "aloam_nodelet/core/executor.h"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <deque>
#include <exception>
#include <optional>

namespace aloam
{
// ---------------------------------------------------------------------------------------------------
// Parallel regions

/// One call of parallelChunks, on its caller's stack. Helpers join it under the executor's mutex and
/// leave it under the same mutex, so the caller may return once it has unlisted the region and seen
/// `joined` drop to 0.
struct Executor::Region
{
  int count = 0;
  int parts = 0;
  ChunkFn fn = nullptr;
  void* context = nullptr;
  std::atomic<int> next{ 1 };  // the next part to claim (part 0 is the caller's)
  std::atomic<bool> failed{ false };
  int caller_cpu = -1;  // where the caller started it (sched_getcpu), for helpers to keep off
  int joined = 0;       // helpers inside; guarded by the executor's mutex
  std::condition_variable done_cv;
  std::mutex error_mutex;
  std::exception_ptr error;

  int bound(int part) const { return static_cast<int>(static_cast<long long>(count) * part / parts); }

  void run(int part)
  {
    try
    {
      fn(context, bound(part), bound(part + 1), part);
    }
    catch (...)
    {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (!error)
      {
        error = std::current_exception();
      }
      failed = true;
    }
  }
};

namespace
{
/// Keeps a helper off its caller's CPU while it works on the caller's region. After an idle gap the
/// kernel may wake the helper on the CPU of the thread that woke it although another one is idle (seen
/// on this project's 2-vCPU virtual machine in half of all regions when paced at 10 Hz, never back to
/// back; why the kernel chose so was not traced further); the two then share one CPU and the
/// region gains nothing from the helper. If the helper finds itself there, it leaves that CPU out of its
/// affinity until the region is done, which moves it to another allowed one; the previous affinity is
/// restored afterwards. Nothing happens where the helper already runs elsewhere, or where it may run on
/// no other CPU (a manager pinned with taskset, a one-CPU cpuset).
class OffCallerCpu
{
public:
  explicit OffCallerCpu(int caller_cpu)
  {
    if (caller_cpu < 0 || caller_cpu >= CPU_SETSIZE || sched_getcpu() != caller_cpu ||
        pthread_getaffinity_np(pthread_self(), sizeof(previous_), &previous_) != 0)
    {
      return;
    }
    cpu_set_t others = previous_;
    CPU_CLR(caller_cpu, &others);
    moved_ = CPU_COUNT(&others) > 0 && pthread_setaffinity_np(pthread_self(), sizeof(others), &others) == 0;
  }
  ~OffCallerCpu()
  {
    if (moved_)
    {
      pthread_setaffinity_np(pthread_self(), sizeof(previous_), &previous_);
    }
  }
  OffCallerCpu(const OffCallerCpu&) = delete;
  OffCallerCpu& operator=(const OffCallerCpu&) = delete;

private:
  cpu_set_t previous_{};
  bool moved_ = false;
};
}  // namespace

int Executor::effectiveParts(int count, int parts, int min_chunk)
{
  return std::clamp(parts, 1, std::max(1, count / std::max(1, min_chunk)));
}

Executor::Executor(int threads) : threads_(std::max(1, threads))
{
  helpers_.reserve(static_cast<std::size_t>(threads_ - 1));
  for (int i = 1; i < threads_; ++i)
  {
    helpers_.emplace_back(&Executor::helperLoop, this);
  }
}

void Executor::runRegionChunks(Region& region)
{
  for (int part = region.next.fetch_add(1); part < region.parts; part = region.next.fetch_add(1))
  {
    if (region.failed.load())
    {
      return;  // skip the chunks not started: the region rethrows
    }
    region.run(part);
  }
}

void Executor::runChunks(int count, int parts, int min_chunk, ChunkFn fn, void* context)
{
  parts = effectiveParts(count, parts, min_chunk);
  if (parts <= 1)
  {
    fn(context, 0, count, 0);
    return;
  }
  Region region;
  region.count = count;
  region.parts = parts;
  region.fn = fn;
  region.context = context;
  if (!helpers_.empty())
  {
    region.caller_cpu = sched_getcpu();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      regions_.push_back(&region);
    }
    if (parts - 1 >= static_cast<int>(helpers_.size()))
    {
      work_cv_.notify_all();
    }
    else
    {
      for (int i = 1; i < parts; ++i)
      {
        work_cv_.notify_one();
      }
    }
  }
  region.run(0);
  // Then whatever the helpers have not claimed (all of it if they are busy with another region).
  runRegionChunks(region);
  if (!helpers_.empty())
  {
    std::unique_lock<std::mutex> lock(mutex_);
    regions_.erase(std::remove(regions_.begin(), regions_.end(), &region), regions_.end());
    region.done_cv.wait(lock, [&] { return region.joined == 0; });
  }
  if (region.error)
  {
    std::rethrow_exception(region.error);
  }
}

void Executor::helperLoop()
{
  std::unique_lock<std::mutex> lock(mutex_);
  while (true)
  {
    work_cv_.wait(lock, [this] { return stop_ || !regions_.empty(); });
    if (stop_)
    {
      return;
    }
    // Regions whose chunks are all claimed are only waiting for their callers: unlist them here, so that
    // this loop sleeps instead of picking them again.
    Region* region = nullptr;
    for (auto it = regions_.begin(); it != regions_.end();)
    {
      if ((*it)->next.load() < (*it)->parts && !(*it)->failed.load())
      {
        region = *it;
        break;
      }
      it = regions_.erase(it);
    }
    if (region == nullptr)
    {
      continue;
    }
    ++region->joined;
    lock.unlock();
    {
      const OffCallerCpu off(region->caller_cpu);
      runRegionChunks(*region);
    }
    lock.lock();
    if (--region->joined == 0)
    {
      region->done_cv.notify_all();  // under the mutex: the caller cannot return before this is done
    }
  }
}

// ---------------------------------------------------------------------------------------------------
// The background lane

struct Executor::JobState
{
  std::function<void()> fn;
  bool pending = false;  // request() since the last start
  std::optional<std::chrono::steady_clock::time_point> deadline;
  bool taken = false;  // handed to the runner or running (on the lane or in runIfPending)
  bool running = false;
  bool released = false;  // its Job is gone
  std::uint64_t runs = 0;

  bool requested() const { return pending || deadline.has_value(); }
  bool due(std::chrono::steady_clock::time_point now) const
  {
    return !taken && !released && (pending || (deadline && now >= *deadline));
  }
};

namespace
{
pid_t threadId()
{
  return static_cast<pid_t>(syscall(SYS_gettid));
}

/// The calling thread's scheduling, to go back to after waiting on idle time.
struct Scheduling
{
  int policy = SCHED_OTHER;
  sched_param param{};
  int nice = 0;

  static Scheduling current()
  {
    Scheduling s;
    pthread_getschedparam(pthread_self(), &s.policy, &s.param);
    s.nice = getpriority(PRIO_PROCESS, static_cast<id_t>(threadId()));
    return s;
  }

  bool restore() const
  {
    return pthread_setschedparam(pthread_self(), policy, &param) == 0 &&
           setpriority(PRIO_PROCESS, static_cast<id_t>(threadId()), nice) == 0;
  }
};

/// Lowering needs no privilege; where SCHED_IDLE is refused, nice 19 serves nearly as well.
void lowerToIdle()
{
  sched_param param{};
  param.sched_priority = 0;
  if (pthread_setschedparam(pthread_self(), SCHED_IDLE, &param) != 0)
  {
    setpriority(PRIO_PROCESS, static_cast<id_t>(threadId()), 19);
  }
}
}  // namespace

struct Executor::Lane
{
  enum class Mode
  {
    kUnknown,
    kSingle,      // the gate raises itself to run a job
    kWithRunner,  // the gate stays idle-priority and hands jobs to the runner
  };

  std::mutex mutex;
  std::condition_variable gate_cv, run_cv, done_cv, mode_cv;
  std::vector<std::shared_ptr<JobState>> jobs;
  std::deque<std::shared_ptr<JobState>> handed;  // kWithRunner: taken, not started
  Mode mode = Mode::kUnknown;
  bool stop = false;
  std::thread gate, runner;

  // Runs `job` (taken) with `lock` held on entry and exit.
  void run(std::unique_lock<std::mutex>& lock, JobState& job)
  {
    job.pending = false;  // requests from here on make one more run
    job.deadline.reset();
    job.running = true;
    lock.unlock();
    job.fn();
    lock.lock();
    job.running = false;
    job.taken = false;
    ++job.runs;
    done_cv.notify_all();
    gate_cv.notify_one();  // it may be due again
  }

  void gateLoop()
  {
    const Scheduling normal = Scheduling::current();
    lowerToIdle();
    const bool can_return = normal.restore();
    {
      std::lock_guard<std::mutex> lock(mutex);
      mode = can_return ? Mode::kSingle : Mode::kWithRunner;
    }
    mode_cv.notify_all();
    std::unique_lock<std::mutex> lock(mutex);
    while (true)
    {
      if (mode == Mode::kSingle)
      {
        lock.unlock();
        lowerToIdle();
        lock.lock();
      }
      std::shared_ptr<JobState> job;
      while (!stop)
      {
        const auto now = std::chrono::steady_clock::now();
        std::optional<std::chrono::steady_clock::time_point> earliest;
        for (const auto& j : jobs)
        {
          if (j->due(now))
          {
            job = j;
            break;
          }
          if (!j->taken && j->deadline && (!earliest || *j->deadline < *earliest))
          {
            earliest = j->deadline;
          }
        }
        if (job)
        {
          break;
        }
        if (earliest)
        {
          gate_cv.wait_until(lock, *earliest);
        }
        else
        {
          gate_cv.wait(lock);
        }
      }
      if (stop)
      {
        return;
      }
      // Running at all means a core was idle: start the job.
      job->taken = true;
      if (mode == Mode::kSingle)
      {
        lock.unlock();
        normal.restore();
        lock.lock();
        run(lock, *job);
      }
      else
      {
        handed.push_back(job);
        run_cv.notify_one();
      }
    }
  }

  void runnerLoop()
  {
    std::unique_lock<std::mutex> lock(mutex);
    while (true)
    {
      run_cv.wait(lock, [this] { return stop || !handed.empty(); });
      if (stop)
      {
        return;
      }
      const std::shared_ptr<JobState> job = handed.front();
      handed.pop_front();
      run(lock, *job);
    }
  }

  void start()
  {
    std::unique_lock<std::mutex> lock(mutex);
    if (mode != Mode::kUnknown || gate.joinable())
    {
      return;
    }
    gate = std::thread(&Lane::gateLoop, this);
    mode_cv.wait(lock, [this] { return mode != Mode::kUnknown; });
    if (mode == Mode::kWithRunner)
    {
      // Started from here, so it has this thread's priority, not the gate's.
      runner = std::thread(&Lane::runnerLoop, this);
    }
  }

  /// Waits for a running job (the thread running it finishes it), then joins.
  void shutdown()
  {
    {
      std::lock_guard<std::mutex> lock(mutex);
      stop = true;
    }
    gate_cv.notify_all();
    run_cv.notify_all();
    done_cv.notify_all();
    if (gate.joinable())
    {
      gate.join();
    }
    if (runner.joinable())
    {
      runner.join();
    }
  }
};

Executor::Job Executor::makeJob(std::function<void()> fn)
{
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!lane_)
    {
      lane_ = std::make_shared<Lane>();
    }
  }
  lane_->start();
  auto state = std::make_shared<JobState>();
  state->fn = std::move(fn);
  {
    std::lock_guard<std::mutex> lock(lane_->mutex);
    lane_->jobs.push_back(state);
  }
  return Job(lane_, state);
}

bool Executor::laneIsSingleThread() const
{
  std::lock_guard<std::mutex> guard(mutex_);
  if (!lane_)
  {
    return false;
  }
  std::lock_guard<std::mutex> lock(lane_->mutex);
  return lane_->mode == Lane::Mode::kSingle;
}

Executor::~Executor()
{
  // The lane first: a job may still enter parallel regions, which need the helpers.
  if (lane_)
  {
    lane_->shutdown();
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  work_cv_.notify_all();
  for (std::thread& helper : helpers_)
  {
    helper.join();
  }
}

Executor::Job::Job(std::shared_ptr<Lane> lane, std::shared_ptr<JobState> state)
  : lane_(std::move(lane)), state_(std::move(state))
{
}

Executor::Job::Job(Job&& other) noexcept = default;

Executor::Job& Executor::Job::operator=(Job&& other) noexcept
{
  if (this != &other)
  {
    release();
    lane_ = std::move(other.lane_);
    state_ = std::move(other.state_);
  }
  return *this;
}

Executor::Job::~Job()
{
  release();
}

void Executor::Job::release()
{
  if (!state_)
  {
    return;
  }
  std::unique_lock<std::mutex> lock(lane_->mutex);
  JobState& job = *state_;
  job.released = true;
  job.pending = false;
  job.deadline.reset();
  auto& handed = lane_->handed;
  const auto it = std::find(handed.begin(), handed.end(), state_);
  if (it != handed.end())
  {
    handed.erase(it);
    job.taken = false;
  }
  lane_->done_cv.wait(lock, [&] { return !job.running; });
  auto& jobs = lane_->jobs;
  jobs.erase(std::remove(jobs.begin(), jobs.end(), state_), jobs.end());
  lane_->done_cv.notify_all();
  lock.unlock();
  state_.reset();
  lane_.reset();
}

void Executor::Job::request()
{
  if (!state_)
  {
    return;
  }
  {
    std::lock_guard<std::mutex> lock(lane_->mutex);
    state_->pending = true;
  }
  lane_->gate_cv.notify_one();
}

void Executor::Job::requestBy(std::chrono::steady_clock::time_point deadline)
{
  if (!state_)
  {
    return;
  }
  {
    std::lock_guard<std::mutex> lock(lane_->mutex);
    state_->deadline = deadline;
  }
  lane_->gate_cv.notify_one();
}

bool Executor::Job::runIfPending()
{
  if (!state_)
  {
    return false;
  }
  std::unique_lock<std::mutex> lock(lane_->mutex);
  JobState& job = *state_;
  if (job.running || !job.requested())
  {
    return false;
  }
  if (job.taken)
  {
    // Handed to the runner, not started: take it back.
    auto& handed = lane_->handed;
    const auto it = std::find(handed.begin(), handed.end(), state_);
    if (it == handed.end())
    {
      return false;
    }
    handed.erase(it);
  }
  job.taken = true;
  lane_->run(lock, job);
  return true;
}

void Executor::Job::waitIdle()
{
  if (!state_)
  {
    return;
  }
  std::unique_lock<std::mutex> lock(lane_->mutex);
  lane_->done_cv.wait(lock,
                      [&] { return lane_->stop || (!state_->requested() && !state_->taken && !state_->running); });
}

void Executor::Job::waitForRuns(std::uint64_t count)
{
  if (!state_)
  {
    return;
  }
  std::unique_lock<std::mutex> lock(lane_->mutex);
  lane_->done_cv.wait(lock, [&] { return lane_->stop || state_->runs >= count; });
}

std::uint64_t Executor::Job::runs() const
{
  if (!state_)
  {
    return 0;
  }
  std::lock_guard<std::mutex> lock(lane_->mutex);
  return state_->runs;
}

}  // namespace aloam
