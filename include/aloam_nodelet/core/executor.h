// The threads of one pipeline instance: its parallel regions and the background lane of its stages.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <type_traits>
#include <vector>

namespace aloam
{
/// Owns every thread a pipeline (or one nodelet) runs work on, and joins them all when destroyed: no
/// global state, so any number of executors may live in one process, each sized for its own stages.
///
/// Parallel regions (parallelChunks) split a loop over the caller and `threads - 1` helper threads. Two
/// threads may enter regions at once (the pose path and a background job of one stage): helpers take
/// chunks of whichever region has some left, and a caller that finds them all busy runs its remaining
/// chunks itself, so a region never waits for another one to finish.
///
/// The background lane runs Jobs: the work a stage does after its result is out (indexing a sweep,
/// updating the map), started only when a core is idle and then run at normal priority (see Job).
///
/// Idle helpers sleep on a condition variable; nothing spins: helpers kept awake after a region, a
/// bounded spin and TBB measured no faster (slower on a loaded machine). A helper the kernel wakes on
/// its caller's CPU leaves that CPU for the region (executor.cpp, OffCallerCpu); otherwise, after idle
/// gaps on a 2-vCPU virtual machine, the two took turns on one CPU. Figures: docs/performance.md#executor.
class Executor
{
public:
  /// `threads`: the threads sharing a parallel region, the caller included (at least 1).
  explicit Executor(int threads);
  /// Waits for running chunks and for a running job, then joins every thread.
  ~Executor();
  Executor(const Executor&) = delete;
  Executor& operator=(const Executor&) = delete;

  int threads() const { return threads_; }

  /// Calls body(begin, end, part) for `parts` contiguous, nearly equal chunks of [0, count) (fewer when
  /// a chunk would hold less than `min_chunk`), part 0 on the calling thread first, and returns when all
  /// are done. Parts beyond the helpers' number run wherever a thread is free, the caller included, so
  /// the chunking (and so the result, when chunks write to disjoint outputs) depends only on
  /// (count, parts, min_chunk), never on the threads or on timing. If a chunk throws, the chunks not yet
  /// started are skipped and the first exception is rethrown here once the started ones are done.
  template <typename Body>
  void parallelChunks(int count, int parts, int min_chunk, Body&& body)
  {
    using B = std::remove_reference_t<Body>;
    runChunks(
        count, parts, min_chunk,
        [](void* context, int begin, int end, int part) { (*static_cast<B*>(context))(begin, end, part); },
        const_cast<void*>(static_cast<const void*>(&body)));
  }

  class Job;
  /// A job on this executor's background lane (see Job). The executor must outlive it.
  Job makeJob(std::function<void()> fn);

  /// Whether the lane starts jobs only on idle time with one thread (it may leave SCHED_IDLE again: root
  /// or a RLIMIT_NICE of 20), or needs a second one (see Job). False until the first makeJob.
  bool laneIsSingleThread() const;

  /// The number of chunks parallelChunks makes of (count, parts, min_chunk).
  static int effectiveParts(int count, int parts, int min_chunk);

private:
  using ChunkFn = void (*)(void* context, int begin, int end, int part);
  struct Region;
  struct Lane;
  struct JobState;

  void runChunks(int count, int parts, int min_chunk, ChunkFn fn, void* context);
  void helperLoop();
  void runRegionChunks(Region& region);

  int threads_;
  mutable std::mutex mutex_;  // guards the region list, stop_ and the creation of lane_
  std::condition_variable work_cv_;
  std::vector<Region*> regions_;  // regions with chunks left to claim
  bool stop_ = false;
  std::vector<std::thread> helpers_;
  std::shared_ptr<Lane> lane_;  // stopped first by the destructor: a job may still use the helpers
};

/// Work a stage does off its latency path, run on the executor's lane after request(), or once a
/// deadline given to requestBy() has passed (requests made while it runs coalesce into one more run).
/// A job starts only when a core is idle, so it delays neither the delivery of the result just published
/// nor the next stage, and then runs at normal priority, so that a stage waiting for a lock the job holds
/// never waits on a starved thread. The lane thread waits under SCHED_IDLE (the kernel runs it only when
/// nothing else wants a core; where SCHED_IDLE is refused, nice 19) and raises itself to normal priority
/// to run the job. Leaving SCHED_IDLE needs privilege (CAP_SYS_NICE, or RLIMIT_NICE 20); without it the
/// lane thread stays the idle-priority gate and hands due jobs to a second, normal-priority thread. On a
/// machine with no idle time nothing starts; the stage must then do the work itself when it needs it
/// (runIfPending, or its own code under its own lock, as the odometry and mapping stages do).
///
/// Destroying a Job waits for its run if it is running, and drops a pending request. A job must not throw.
/// A default-constructed Job does nothing.
class Executor::Job
{
public:
  Job() = default;
  Job(Job&&) noexcept;
  Job& operator=(Job&&) noexcept;
  ~Job();

  /// Runs the job as soon as a core is idle.
  void request();
  /// Runs the job once `deadline` has passed and a core is idle, or earlier if request() comes first.
  void requestBy(std::chrono::steady_clock::time_point deadline);
  /// If a run is requested (request or deadline) and not started, runs it here, now, and returns true
  /// (the request is consumed). False if nothing is pending or the lane is running it. Must not be called
  /// holding a lock the job takes if the lane may be running it (this never waits for the lane).
  bool runIfPending();
  /// Waits until the job is neither requested nor running (tests, shutdown). With a deadline pending
  /// that includes the deadline's run.
  void waitIdle();
  /// Waits until `count` runs have completed (tests).
  void waitForRuns(std::uint64_t count);
  /// Runs completed so far (on the lane or through runIfPending).
  std::uint64_t runs() const;

private:
  friend class Executor;
  Job(std::shared_ptr<Lane> lane, std::shared_ptr<JobState> state);
  void release();

  std::shared_ptr<Lane> lane_;
  std::shared_ptr<JobState> state_;
};

/// How many chunks a loop whose iterations differ in cost (correspondence searches, residuals) is cut
/// into per thread: a thread done early takes the chunks left, so a late or slow helper holds nobody up.
/// 8 measured best of 1 / 4 / 8 (docs/performance.md#executor).
inline constexpr int kChunksPerThread = 8;

/// executor->parallelChunks(...), or without an executor every chunk in turn on the calling thread (the
/// same chunks, so the same results).
template <typename Body>
void parallelChunks(Executor* executor, int count, int parts, int min_chunk, Body&& body)
{
  if (executor != nullptr)
  {
    executor->parallelChunks(count, parts, min_chunk, body);
    return;
  }
  parts = Executor::effectiveParts(count, parts, min_chunk);
  for (int part = 0; part < parts; ++part)
  {
    body(static_cast<int>(static_cast<long long>(count) * part / parts),
         static_cast<int>(static_cast<long long>(count) * (part + 1) / parts), part);
  }
}

}  // namespace aloam
