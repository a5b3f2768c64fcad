// parallelChunks: every index once, whatever the split; concurrent callers; the shared helper teams.
#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "aloam_nodelet/core/parallel.h"

namespace aloam
{
namespace
{
TEST(Parallel, EveryIndexOnceInContiguousChunks)
{
  for (const int count : { 0, 1, 7, 1000, 4097 })
  {
    for (const int parts : { 1, 2, 3, 8 })
    {
      std::vector<int> hits(static_cast<std::size_t>(count), 0);
      std::vector<int> part_of(static_cast<std::size_t>(count), -1);
      parallelChunks(count, parts, 1,
                     [&](int begin, int end, int part)
                     {
                       for (int i = begin; i < end; ++i)
                       {
                         ++hits[i];
                         part_of[i] = part;
                       }
                     });
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

TEST(Parallel, TooLittleWorkStaysOnTheCallingThread)
{
  const std::thread::id caller = std::this_thread::get_id();
  std::atomic<int> elsewhere{ 0 };
  parallelChunks(100, 4, 64,
                 [&](int, int, int)
                 {
                   if (std::this_thread::get_id() != caller)
                   {
                     ++elsewhere;
                   }
                 });
  EXPECT_EQ(elsewhere.load(), 0);
}

TEST(Parallel, TeamsAreSharedBetweenThreadsAndReused)
{
  // A team given back is lent again, to any thread: the stages of a pipeline run on different threads.
  detail::HelperTeam* first = detail::lendTeam(1);
  detail::returnTeam(first);
  detail::HelperTeam* again = nullptr;
  std::thread(
      [&]
      {
        again = detail::lendTeam(1);
        detail::returnTeam(again);
      })
      .join();
  EXPECT_EQ(first, again);
  // While one is lent, another caller gets a team of its own.
  detail::HelperTeam* a = detail::lendTeam(2);
  detail::HelperTeam* b = detail::lendTeam(1);
  EXPECT_NE(a, b);
  EXPECT_GE(a->size(), 2u);
  detail::returnTeam(b);
  detail::returnTeam(a);
}

TEST(Parallel, ConcurrentCallersDoNotMix)
{
  constexpr int kCount = 20000;
  std::vector<std::thread> callers;
  std::vector<long long> sums(4, 0);
  for (int c = 0; c < 4; ++c)
  {
    callers.emplace_back(
        [&, c]
        {
          for (int round = 0; round < 50; ++round)
          {
            std::vector<long long> partial(2, 0);
            parallelChunks(kCount, 2, 1,
                           [&](int begin, int end, int part)
                           {
                             for (int i = begin; i < end; ++i)
                             {
                               partial[part] += i;
                             }
                           });
            sums[c] += partial[0] + partial[1];
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

TEST(Parallel, ThrowingOnTheCallingThreadWaitsForTheHelpers)
{
  std::atomic<int> helper_done{ 0 };
  EXPECT_THROW(parallelChunks(2, 2, 1,
                              [&](int, int, int part)
                              {
                                if (part == 0)
                                {
                                  throw std::runtime_error("chunk 0 failed");
                                }
                                std::this_thread::sleep_for(std::chrono::milliseconds(20));
                                ++helper_done;
                              }),
               std::runtime_error);
  EXPECT_EQ(helper_done.load(), 1);  // the helper finished before the call returned
  // And the team came back: the next region works.
  int total = 0;
  std::vector<int> parts(2, 0);
  parallelChunks(2, 2, 1, [&](int begin, int end, int part) { parts[part] = end - begin; });
  total = parts[0] + parts[1];
  EXPECT_EQ(total, 2);
}

}  // namespace
}  // namespace aloam
