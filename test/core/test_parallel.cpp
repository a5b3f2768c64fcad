// Executor: parallel regions (every index once, whatever the split; concurrent callers; busy helpers;
// exceptions), the background lane (requests, deadlines, coalescing, priority, running a pending job on the
// caller, destruction while a job runs) and its threads (all joined). No test relies on timing: they wait
// on conditions, so they hold on a loaded machine and under ThreadSanitizer.
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "thread_support.h"
#include "aloam_nodelet/core/executor.h"

namespace aloam
{
namespace
{
using Clock = std::chrono::steady_clock;

using aloam_test::Latch;
using aloam_test::threadId;

using aloam_test::settledThreadCount;
using aloam_test::threadsDropTo;
using aloam_test::threadsOfThisProcess;

TEST(Executor, EveryIndexOnceInContiguousChunks)
{
  for (const int threads : { 1, 3 })
  {
    Executor executor(threads);
    for (Executor* e : { &executor, static_cast<Executor*>(nullptr) })
    {
      for (const int count : { 0, 1, 7, 1000, 4097 })
      {
        for (const int parts : { 1, 2, 3, 8 })
        {
          std::vector<int> hits(static_cast<std::size_t>(count), 0);
          std::vector<int> part_of(static_cast<std::size_t>(count), -1);
          std::vector<int> calls(static_cast<std::size_t>(parts), 0);
          parallelChunks(e, count, parts, 1,
                         [&](int begin, int end, int part)
                         {
                           ++calls[part];
                           for (int i = begin; i < end; ++i)
                           {
                             ++hits[i];
                             part_of[i] = part;
                           }
                         });
          // Every part once, whatever the threads: per-part outputs do not depend on them.
          for (int p = 0; p < Executor::effectiveParts(count, parts, 1); ++p)
          {
            EXPECT_EQ(calls[p], 1) << "threads " << threads << " count " << count << " parts " << parts;
          }
          for (int i = 0; i < count; ++i)
          {
            ASSERT_EQ(hits[i], 1) << "count " << count << " parts " << parts << " index " << i;
            if (i > 0)
            {
              EXPECT_GE(part_of[i], part_of[i - 1]);  // chunks in order
            }
          }
        }
      }
    }
  }
}

TEST(Executor, TooLittleWorkStaysOnTheCallingThread)
{
  Executor executor(4);
  const std::thread::id caller = std::this_thread::get_id();
  std::atomic<int> elsewhere{ 0 };
  std::atomic<int> calls{ 0 };
  executor.parallelChunks(100, 4, 64,
                          [&](int, int, int)
                          {
                            ++calls;
                            if (std::this_thread::get_id() != caller)
                            {
                              ++elsewhere;
                            }
                          });
  EXPECT_EQ(calls.load(), 1);
  EXPECT_EQ(elsewhere.load(), 0);
}

TEST(Executor, ConcurrentCallersDoNotMix)
{
  constexpr int kCount = 20000;
  Executor executor(2);  // fewer threads than callers: most chunks run on their callers
  std::vector<std::thread> callers;
  std::vector<long long> sums(4, 0);
  for (int c = 0; c < 4; ++c)
  {
    callers.emplace_back(
        [&, c]
        {
          for (int round = 0; round < 50; ++round)
          {
            std::vector<long long> partial(3, 0);
            executor.parallelChunks(kCount, 3, 1,
                                    [&](int begin, int end, int part)
                                    {
                                      for (int i = begin; i < end; ++i)
                                      {
                                        partial[part] += i;
                                      }
                                    });
            sums[c] += partial[0] + partial[1] + partial[2];
          }
        });
  }
  for (std::thread& t : callers)
  {
    t.join();
  }
  for (const long long sum : sums)
  {
    EXPECT_EQ(sum, 50LL * kCount * (kCount - 1) / 2);
  }
}

// One region holds the only helper (or its own caller) until a second region, from another thread, is
// done: the second must complete on its caller rather than wait for the helper.
TEST(Executor, ARegionFindingTheHelpersBusyStillCompletes)
{
  Executor executor(2);
  Latch holding, second_done;
  std::thread first(
      [&]
      {
        executor.parallelChunks(2, 2, 1,
                                [&](int, int, int part)
                                {
                                  if (part == 1)
                                  {
                                    holding.open();
                                    second_done.wait();
                                  }
                                });
      });
  holding.wait();
  std::vector<int> parts(4, 0);
  executor.parallelChunks(4, 4, 1, [&](int begin, int end, int part) { parts[part] = end - begin; });
  second_done.open();
  first.join();
  EXPECT_EQ(parts, std::vector<int>({ 1, 1, 1, 1 }));
}

TEST(Executor, RegionsNestInsideChunks)
{
  Executor executor(3);
  std::vector<int> sums(3, 0);
  executor.parallelChunks(3, 3, 1,
                          [&](int, int, int outer)
                          {
                            std::vector<int> inner(4, 0);
                            executor.parallelChunks(400, 4, 1,
                                                    [&](int begin, int end, int part) { inner[part] = end - begin; });
                            sums[outer] = inner[0] + inner[1] + inner[2] + inner[3];
                          });
  EXPECT_EQ(sums, std::vector<int>({ 400, 400, 400 }));
}

TEST(Executor, AThrowingChunkReachesTheCallerOnceTheOthersAreDone)
{
  Executor executor(3);
  for (const int throwing : { 0, 1, 5 })
  {
    std::atomic<int> inside{ 0 };
    std::atomic<int> ran{ 0 };
    EXPECT_THROW(executor.parallelChunks(6, 6, 1,
                                         [&](int, int, int part)
                                         {
                                           ++inside;
                                           ++ran;
                                           if (part == throwing)
                                           {
                                             --inside;
                                             throw std::runtime_error("chunk failed");
                                           }
                                           --inside;
                                         }),
                 std::runtime_error)
        << "throwing part " << throwing;
    EXPECT_EQ(inside.load(), 0) << "a chunk still ran after the region returned";
    EXPECT_GE(ran.load(), 1);
    // The executor still works.
    std::vector<int> parts(3, 0);
    executor.parallelChunks(3, 3, 1, [&](int begin, int end, int part) { parts[part] = end - begin; });
    EXPECT_EQ(parts, std::vector<int>({ 1, 1, 1 }));
  }
}

cpu_set_t affinityOf(pid_t tid)
{
  cpu_set_t mask;
  CPU_ZERO(&mask);
  EXPECT_EQ(sched_getaffinity(tid, sizeof(mask), &mask), 0);
  return mask;
}

// A helper may leave its caller's CPU for a region (executor.cpp, OffCallerCpu): inside a chunk its
// affinity is the original one or that less one CPU, and after the region it is the original again. To
// make the helper start on its caller's CPU, the caller is pinned to the CPU the helper ran on last.
TEST(Executor, HelpersGetTheirAffinityBackAfterARegion)
{
  const cpu_set_t original = affinityOf(0);
  if (CPU_COUNT(&original) < 2)
  {
    GTEST_SKIP() << "one CPU allowed: a helper has nowhere to move";
  }
  Executor executor(2);
  std::mutex mutex;
  std::vector<pid_t> helpers;
  int helper_cpu = -1;
  int narrowed = 0;
  bool narrowed_wrongly = false;
  const pid_t caller = threadId();
  for (int round = 0; round < 200; ++round)
  {
    int last_helper_cpu = -1;
    {
      std::lock_guard<std::mutex> lock(mutex);
      last_helper_cpu = helper_cpu;
    }
    if (round % 2 == 1 && last_helper_cpu >= 0)
    {
      cpu_set_t there;
      CPU_ZERO(&there);
      CPU_SET(last_helper_cpu, &there);
      ASSERT_EQ(sched_setaffinity(0, sizeof(there), &there), 0);
    }
    std::vector<int> parts(4, 0);
    executor.parallelChunks(4, 4, 1,
                            [&](int begin, int end, int part)
                            {
                              parts[part] = end - begin;
                              const pid_t tid = threadId();
                              if (tid == caller)
                              {
                                return;
                              }
                              const cpu_set_t inside = affinityOf(0);
                              cpu_set_t both;
                              CPU_AND(&both, &inside, &original);
                              std::lock_guard<std::mutex> lock(mutex);
                              helper_cpu = sched_getcpu();
                              const int removed = CPU_COUNT(&original) - CPU_COUNT(&inside);
                              narrowed += removed > 0 ? 1 : 0;
                              narrowed_wrongly |= !CPU_EQUAL(&both, &inside) || removed > 1;
                              if (std::find(helpers.begin(), helpers.end(), tid) == helpers.end())
                              {
                                helpers.push_back(tid);
                              }
                            });
    ASSERT_EQ(sched_setaffinity(0, sizeof(original), &original), 0);
    ASSERT_EQ(parts, std::vector<int>({ 1, 1, 1, 1 }));
  }
  EXPECT_FALSE(narrowed_wrongly);
  std::lock_guard<std::mutex> lock(mutex);
  std::printf("helper chunks run off a narrowed affinity: %d\n", narrowed);
  for (const pid_t tid : helpers)
  {
    const cpu_set_t after = affinityOf(tid);
    EXPECT_TRUE(CPU_EQUAL(&after, &original)) << "helper " << tid << " kept a narrowed affinity";
  }
}

// Pinned to one CPU (taskset, a one-CPU cpuset) a helper has nowhere to go: it stays, and the regions
// complete as ever.
TEST(Executor, RegionsCompleteWithTheProcessPinnedToOneCpu)
{
  std::thread pinned(
      [&]
      {
        cpu_set_t one;
        CPU_ZERO(&one);
        CPU_SET(sched_getcpu(), &one);
        ASSERT_EQ(sched_setaffinity(0, sizeof(one), &one), 0);
        Executor executor(3);  // its helpers inherit the one CPU
        for (int round = 0; round < 50; ++round)
        {
          std::vector<int> parts(6, 0);
          std::vector<int> counts(6, 0);
          executor.parallelChunks(6, 6, 1,
                                  [&](int begin, int end, int part)
                                  {
                                    parts[part] = end - begin;
                                    const cpu_set_t inside = affinityOf(0);
                                    counts[part] = CPU_COUNT(&inside);
                                  });
          ASSERT_EQ(parts, std::vector<int>(6, 1));
          ASSERT_EQ(counts, std::vector<int>(6, 1));
        }
      });
  pinned.join();
}

TEST(Executor, ThreadsAreJoinedOnDestruction)
{
  Executor{ 2 }.parallelChunks(2, 2, 1, [](int, int, int) {});  // threads a sanitizer starts on first use
  const std::size_t before = settledThreadCount();              // the warm-up's helper may linger for a moment
  {
    Executor executor(4);
    std::vector<int> parts(4, 0);
    executor.parallelChunks(4, 4, 1, [&](int begin, int end, int part) { parts[part] = end - begin; });
    Executor::Job job = executor.makeJob([] {});
    job.request();
    job.waitForRuns(1);
    // Helpers (3) and the lane (1, or 2 without the privilege to leave SCHED_IDLE).
    EXPECT_GE(threadsOfThisProcess(), before + 4);
    EXPECT_LE(threadsOfThisProcess(), before + 5);
  }
  EXPECT_TRUE(threadsDropTo(before)) << threadsOfThisProcess() << " threads, " << before << " before";
}

TEST(ExecutorJob, RunsOnRequestAndCoalesces)
{
  Executor executor(1);
  Latch started, release;
  std::atomic<int> runs{ 0 };
  Executor::Job job = executor.makeJob(
      [&]
      {
        if (runs.load() == 0)
        {
          started.open();
          release.wait();
        }
        ++runs;
      });
  job.request();
  started.wait();  // the first run is under way, held
  job.request();
  job.request();  // both while it runs: one more run
  release.open();
  job.waitIdle();
  EXPECT_EQ(runs.load(), 2);
  EXPECT_EQ(job.runs(), 2u);
  EXPECT_FALSE(job.runIfPending());  // nothing left over
}

TEST(ExecutorJob, DeadlineRunsNotBeforeIt)
{
  Executor executor(1);
  std::atomic<long long> ran_at_ns{ 0 };
  Executor::Job job = executor.makeJob([&] { ran_at_ns = Clock::now().time_since_epoch().count(); });
  const auto deadline = Clock::now() + std::chrono::milliseconds(30);
  job.requestBy(deadline);
  job.waitIdle();
  EXPECT_EQ(job.runs(), 1u);
  EXPECT_GE(ran_at_ns.load(), deadline.time_since_epoch().count());
}

TEST(ExecutorJob, RequestBeatsTheDeadlineAndUsesItUp)
{
  Executor executor(1);
  Executor::Job job = executor.makeJob([] {});
  job.requestBy(Clock::now() + std::chrono::hours(1));
  job.request();
  job.waitForRuns(1);
  // The deadline went with that run: nothing is pending (or this would run it here).
  EXPECT_FALSE(job.runIfPending());
  EXPECT_EQ(job.runs(), 1u);
}

TEST(ExecutorJob, RunIfPendingRunsOnTheCaller)
{
  Executor executor(1);
  std::atomic<bool> on_caller{ false };
  const std::thread::id caller = std::this_thread::get_id();
  Executor::Job job = executor.makeJob([&] { on_caller = std::this_thread::get_id() == caller; });
  EXPECT_FALSE(job.runIfPending());  // nothing requested
  job.requestBy(Clock::now() + std::chrono::hours(1));
  EXPECT_TRUE(job.runIfPending());
  EXPECT_TRUE(on_caller.load());
  EXPECT_EQ(job.runs(), 1u);
  EXPECT_FALSE(job.runIfPending());  // the request was consumed
}

TEST(ExecutorJob, StopsWhileWaitingForADeadline)
{
  std::atomic<int> runs{ 0 };
  {
    Executor executor(2);
    Executor::Job job = executor.makeJob([&] { ++runs; });
    job.requestBy(Clock::now() + std::chrono::hours(1));
  }  // would hang here for an hour if destruction waited for the deadline
  EXPECT_EQ(runs.load(), 0);
  // The executor gone first, the job after it.
  auto executor = std::make_unique<Executor>(1);
  Executor::Job job = executor->makeJob([&] { ++runs; });
  job.requestBy(Clock::now() + std::chrono::hours(1));
  executor.reset();
  job.request();   // nothing runs it any more
  job.waitIdle();  // and this does not wait for it
  EXPECT_EQ(runs.load(), 0);
}

// Destroying the job (as a stage does on unload) or the executor while a run is under way waits for it.
TEST(ExecutorJob, DestructionWaitsForARunningJob)
{
  for (const bool destroy_executor : { false, true })
  {
    auto executor = std::make_unique<Executor>(2);
    Executor* const raw = executor.get();  // the unique_ptr is cleared before the executor is destroyed
    Latch started, destroying;
    std::atomic<bool> finished{ false };
    std::atomic<bool> destroyed{ false };
    std::atomic<bool> destroyed_before_finish{ false };
    auto job = std::make_unique<Executor::Job>(executor->makeJob(
        [&]
        {
          started.open();
          destroying.wait();
          // The destructor has been called (or is about to be): it must not have returned.
          std::vector<int> parts(2, 0);
          raw->parallelChunks(2, 2, 1, [&](int begin, int end, int part) { parts[part] = end - begin; });
          destroyed_before_finish = destroyed.load();
          finished = parts[0] + parts[1] == 2;
        }));
    job->request();
    started.wait();
    std::thread destroyer(
        [&]
        {
          destroying.open();
          if (destroy_executor)
          {
            executor.reset();
          }
          else
          {
            job.reset();
          }
          destroyed = true;
        });
    destroyer.join();
    EXPECT_TRUE(finished.load()) << (destroy_executor ? "executor" : "job");
    EXPECT_FALSE(destroyed_before_finish.load());
  }
}

// Only the start waits for idle time: the job itself runs at the priority of the thread that made the
// executor, so a stage waiting on the job's lock never waits on a thread the scheduler starves.
TEST(ExecutorJob, RunsAtTheCreatorsPriority)
{
  Executor executor(1);
  const int nice_here = getpriority(PRIO_PROCESS, static_cast<id_t>(threadId()));
  std::atomic<int> policy{ -1 };
  std::atomic<int> nice{ 99 };
  Executor::Job job = executor.makeJob(
      [&]
      {
        policy = sched_getscheduler(0);
        nice = getpriority(PRIO_PROCESS, static_cast<id_t>(threadId()));
      });
  job.request();
  job.waitForRuns(1);
  EXPECT_EQ(policy.load(), SCHED_OTHER);
  EXPECT_EQ(nice.load(), nice_here);
  // Twice: the lane goes back to waiting on idle time in between.
  job.request();
  job.waitForRuns(2);
  EXPECT_EQ(policy.load(), SCHED_OTHER);
}

// The pose path's regions and a background job's regions on one executor at once.
TEST(ExecutorJob, JobsAndRegionsShareTheExecutor)
{
  constexpr int kCount = 5000;
  Executor executor(2);
  std::atomic<long long> job_sum{ 0 };
  Executor::Job job = executor.makeJob(
      [&]
      {
        std::vector<long long> partial(2, 0);
        executor.parallelChunks(kCount, 2, 1,
                                [&](int begin, int end, int part)
                                {
                                  for (int i = begin; i < end; ++i)
                                  {
                                    partial[part] += i;
                                  }
                                });
        job_sum += partial[0] + partial[1];
      });
  long long sum = 0;
  for (int round = 0; round < 20; ++round)
  {
    job.request();
    std::vector<long long> partial(2, 0);
    executor.parallelChunks(kCount, 2, 1,
                            [&](int begin, int end, int part)
                            {
                              for (int i = begin; i < end; ++i)
                              {
                                partial[part] += i;
                              }
                            });
    sum += partial[0] + partial[1];
  }
  job.waitIdle();
  const long long one = static_cast<long long>(kCount) * (kCount - 1) / 2;
  EXPECT_EQ(sum, 20 * one);
  EXPECT_EQ(job_sum.load(), static_cast<long long>(job.runs()) * one);
  EXPECT_GE(job.runs(), 1u);
}

}  // namespace
}  // namespace aloam
