// BackgroundWorker: runs on request, at a deadline or earlier on request, coalesces, and stops cleanly.
#include <atomic>
#include <chrono>
#include <thread>

#include <gtest/gtest.h>

#include "background_worker.h"

namespace aloam_nodelet
{
namespace
{
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

// Waits (at most a few seconds, the machine may be busy) until `runs` reaches `count`.
bool waitFor(const std::atomic<int>& runs, int count)
{
  const auto until = Clock::now() + std::chrono::seconds(5);
  while (runs.load() < count && Clock::now() < until)
  {
    std::this_thread::sleep_for(milliseconds(1));
  }
  return runs.load() >= count;
}

TEST(BackgroundWorker, RunsOnRequestAndCoalesces)
{
  std::atomic<int> runs{ 0 };
  std::atomic<bool> release{ false };
  BackgroundWorker worker(
      [&]
      {
        while (!release.load())
        {
          std::this_thread::sleep_for(milliseconds(1));
        }
        ++runs;
      });
  worker.request();
  std::this_thread::sleep_for(milliseconds(20));  // the first run is under way, held
  worker.request();
  worker.request();  // both while it runs: one more run
  release = true;
  ASSERT_TRUE(waitFor(runs, 2));
  std::this_thread::sleep_for(milliseconds(50));
  EXPECT_EQ(runs.load(), 2);
}

TEST(BackgroundWorker, DeadlineRunsNotBeforeIt)
{
  std::atomic<int> runs{ 0 };
  std::atomic<long long> ran_at_ns{ 0 };
  BackgroundWorker worker(
      [&]
      {
        ran_at_ns = Clock::now().time_since_epoch().count();
        ++runs;
      });
  const auto deadline = Clock::now() + milliseconds(80);
  worker.requestBy(deadline);
  std::this_thread::sleep_for(milliseconds(30));
  EXPECT_EQ(runs.load(), 0);
  ASSERT_TRUE(waitFor(runs, 1));
  EXPECT_GE(ran_at_ns.load(), deadline.time_since_epoch().count());
}

TEST(BackgroundWorker, RequestBeatsTheDeadline)
{
  std::atomic<int> runs{ 0 };
  BackgroundWorker worker([&] { ++runs; });
  const auto start = Clock::now();
  worker.requestBy(start + std::chrono::seconds(10));
  std::this_thread::sleep_for(milliseconds(10));
  worker.request();
  ASSERT_TRUE(waitFor(runs, 1));
  EXPECT_LT(Clock::now() - start, std::chrono::seconds(5));
  // The deadline was used up by that run: nothing more comes.
  std::this_thread::sleep_for(milliseconds(50));
  EXPECT_EQ(runs.load(), 1);
}

TEST(BackgroundWorker, StopsWhileWaitingForADeadline)
{
  std::atomic<int> runs{ 0 };
  const auto start = Clock::now();
  {
    BackgroundWorker worker([&] { ++runs; });
    worker.requestBy(start + std::chrono::seconds(30));
    std::this_thread::sleep_for(milliseconds(10));
  }
  EXPECT_LT(Clock::now() - start, std::chrono::seconds(5));
  EXPECT_EQ(runs.load(), 0);
}

}  // namespace
}  // namespace aloam_nodelet

namespace aloam_nodelet
{
namespace
{
// Only the start waits for idle time: the job itself runs at the stage's (normal) priority, so a stage
// waiting on the job's lock never waits on a thread the scheduler starves.
TEST(BackgroundWorker, JobRunsAtNormalPriority)
{
  std::atomic<int> runs{ 0 };
  std::atomic<int> policy{ -1 };
  BackgroundWorker worker(
      [&]
      {
        policy = sched_getscheduler(0);
        ++runs;
      });
  worker.request();
  ASSERT_TRUE(waitFor(runs, 1));
  EXPECT_EQ(policy.load(), SCHED_OTHER);
}

}  // namespace
}  // namespace aloam_nodelet
