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
/// Idle helpers sleep on a condition variable; nothing spins. Measured (issue 13) on KITTI 00 frames
/// 0-100, 2 threads per stage, on a 2-vCPU machine loaded by other builds, medians of interleaved runs,
/// registration / odometry / mapping / map update / to the pose, ms (aloam_bench --only kitti, 6 runs each):
///   these helpers                                    9.8 /  8.4 / 15.1 / 12.3 / 35.1
///   helpers awake for 2 ms after a region (yield)   12.7 / 11.2 / 21.8 / 17.7 / 46.7
///   TBB (task_arena of `threads`, parallel_for)     11.2 / 10.7 / 19.7 / 15.7 / 42.5
/// Paced at 10 Hz (--pace 10, 4 runs) to the pose 33.5 / 41.9 / 39.0; live through the nodelets at 10 Hz
/// (scripts/bench.sh --live-only, 4 runs) latency median 32.5 / 32.2 / 33.3, p90 38.6 / 42.9 / 44.0.
/// On a shared machine a spinning thread takes the core the stage needs; in the least loaded round the
/// three were within 4 % (28.1 / 27.0 / 27.1). TBB measured more than 5 % slower, so it is not used.
/// A bounded spin (helpers and the caller awake 0 / 50 / 200 us before sleeping) paced at 10 Hz, 3
/// interleaved rounds, to the pose medians 30.9 / 30.0 / 29.4 ms: within run-to-run noise, so no spin.
/// A wake-up itself is cheap (a condition-variable wake takes about 20 us here after 70 ms idle), but
/// where it lands is not: paced at 10 Hz on this 2-vCPU virtual machine, the kernel woke the helper on
/// its caller's CPU in about half of all regions (none back to back) while the other CPU idled, so the
/// two took turns on one CPU: the caller waited 8.3 ms per sweep in the run queue
/// (/proc/thread-self/schedstat), and to the pose took 29.7 ms paced against 18-21 ms back to back. A
/// helper that finds itself on its caller's CPU therefore leaves it for the region (executor.cpp,
/// OffCallerCpu): run-queue wait 0.35 ms, to the pose 23.0 ms paced (2 interleaved rounds, 29.7 / 27.8
/// -> 23.0 / 22.7 ms), live through the nodelets (3 interleaved rounds) median 30.8 -> 27.0 ms. Caches
/// cold after the idle gap cost the rest (the caller's share of the regions 12.8 ms per sweep back to
/// back, 16.5 ms paced).
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
/// 8 measured best of 1 / 4 / 8 (KITTI 00, 2 threads, paced at 10 Hz: to the pose 23.5 / 23.4 / 21.5 ms
/// mean in one round, 23.9 / 23.7 / 23.1 in another; live medians over 3 interleaved rounds 32.1 vs
/// 31.2 ms with 1 and 8).
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
