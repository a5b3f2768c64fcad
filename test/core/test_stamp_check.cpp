// Tests of StampCheck, the time policy of the stages: every verdict, the clock it keeps and its counts.
#include <cstdint>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "aloam_nodelet/core/stamp_check.h"

namespace aloam
{
namespace
{
constexpr std::int64_t kMs = 1'000'000;                             // nanoseconds
constexpr std::int64_t kSweep = 100 * kMs;                          // 10 Hz
constexpr std::int64_t kStart = 1'700'000'000LL * 1'000'000'000LL;  // a wall-clock stamp (2023), in ns

StampCheckConfig tenHertz()
{
  StampCheckConfig config;
  config.scan_period = 0.1;
  config.max_gap_sweeps = 5.0;
  config.jump_back_tolerance = 1.0;
  return config;
}

TEST(StampCheck, FirstThenInSequence)
{
  StampCheck check(tenHertz());
  EXPECT_EQ(check.check(kStart), StampVerdict::kFirst);
  EXPECT_DOUBLE_EQ(check.lastStep(), 0.0);
  for (int i = 1; i <= 20; ++i)
  {
    EXPECT_EQ(check.check(kStart + i * kSweep), StampVerdict::kInSequence) << "sweep " << i;
    EXPECT_NEAR(check.lastStep(), 0.1, 1e-12);
  }
  EXPECT_EQ(check.counts().taken, 21u);
  EXPECT_EQ(check.counts().duplicates + check.counts().out_of_order + check.counts().gaps + check.counts().jumps_back,
            0u);
}

TEST(StampCheck, DuplicateIsDroppedAndCounted)
{
  StampCheck check(tenHertz());
  check.check(kStart);
  check.check(kStart + kSweep);
  EXPECT_EQ(check.check(kStart + kSweep), StampVerdict::kDuplicate);
  EXPECT_FALSE(isTaken(StampVerdict::kDuplicate));
  EXPECT_EQ(check.check(kStart + kSweep), StampVerdict::kDuplicate);
  EXPECT_EQ(check.counts().duplicates, 2u);
  EXPECT_EQ(check.counts().taken, 2u);
  // The next sweep is still in sequence with the one taken.
  EXPECT_EQ(check.check(kStart + 2 * kSweep), StampVerdict::kInSequence);
}

TEST(StampCheck, OneNanosecondApartIsNoDuplicate)
{
  StampCheck check(tenHertz());
  check.check(kStart);
  EXPECT_EQ(check.check(kStart + 1), StampVerdict::kInSequence);
  EXPECT_EQ(check.check(kStart), StampVerdict::kOutOfOrder);
}

TEST(StampCheck, SmallStepBackIsOutOfOrderAndKeepsTheClock)
{
  StampCheck check(tenHertz());
  check.check(kStart);
  check.check(kStart + kSweep);
  check.check(kStart + 2 * kSweep);
  // A late sweep (one or several periods back, within the tolerance) is dropped...
  EXPECT_EQ(check.check(kStart + kSweep + 50 * kMs), StampVerdict::kOutOfOrder);
  EXPECT_NEAR(check.lastStep(), -0.05, 1e-12);
  EXPECT_EQ(check.check(kStart - 500 * kMs), StampVerdict::kOutOfOrder);
  EXPECT_TRUE(!isTaken(StampVerdict::kOutOfOrder));
  EXPECT_EQ(check.counts().out_of_order, 2u);
  // ... and does not move the clock back: the next sweep is measured from the last one taken.
  EXPECT_EQ(check.check(kStart + 3 * kSweep), StampVerdict::kInSequence);
  EXPECT_NEAR(check.lastStep(), 0.1, 1e-12);
}

TEST(StampCheck, BigStepBackIsARestart)
{
  StampCheck check(tenHertz());
  for (int i = 0; i < 50; ++i)
  {
    check.check(kStart + i * kSweep);
  }
  // A looping bag: back to the first stamp, 4.9 s earlier.
  EXPECT_EQ(check.check(kStart), StampVerdict::kJumpedBack);
  EXPECT_TRUE(isTaken(StampVerdict::kJumpedBack));
  EXPECT_NEAR(check.lastStep(), -4.9, 1e-9);
  EXPECT_EQ(check.counts().jumps_back, 1u);
  // The new run goes on from there.
  EXPECT_EQ(check.check(kStart + kSweep), StampVerdict::kInSequence);
  EXPECT_EQ(check.check(kStart + kSweep), StampVerdict::kDuplicate);
}

TEST(StampCheck, ToleranceSeparatesLateSweepsFromRestarts)
{
  StampCheckConfig config = tenHertz();
  config.jump_back_tolerance = 0.25;
  StampCheck check(config);
  check.check(kStart + 10 * kSweep);
  EXPECT_EQ(check.check(kStart + 8 * kSweep), StampVerdict::kOutOfOrder);  // 0.2 s back
  EXPECT_EQ(check.check(kStart + 7 * kSweep), StampVerdict::kJumpedBack);  // 0.3 s back
}

TEST(StampCheck, LongStepForwardIsAGap)
{
  StampCheck check(tenHertz());
  check.check(kStart);
  // Five periods is the limit (a few lost sweeps), more is a gap.
  EXPECT_EQ(check.check(kStart + 5 * kSweep), StampVerdict::kInSequence);
  EXPECT_EQ(check.check(kStart + 10 * kSweep + 1), StampVerdict::kGap);
  EXPECT_TRUE(isTaken(StampVerdict::kGap));
  EXPECT_NEAR(check.lastStep(), 0.5, 1e-9);
  EXPECT_EQ(check.check(kStart + 11 * kSweep), StampVerdict::kInSequence);
  EXPECT_EQ(check.check(kStart + 11 * kSweep + 3'600'000 * kMs), StampVerdict::kGap);  // an hour later
  EXPECT_EQ(check.counts().gaps, 2u);
  EXPECT_EQ(check.counts().taken, 5u);
}

TEST(StampCheck, GapLimitFollowsTheConfiguration)
{
  StampCheck check(tenHertz());
  check.check(kStart);
  EXPECT_EQ(check.check(kStart + 3 * kSweep), StampVerdict::kInSequence);
  StampCheckConfig config = check.config();
  config.max_gap_sweeps = 2.0;
  check.setConfig(config);
  EXPECT_EQ(check.check(kStart + 6 * kSweep), StampVerdict::kGap);
  config.scan_period = 0.05;  // a 20 Hz sensor: 2 periods are 0.1 s
  check.setConfig(config);
  EXPECT_EQ(check.check(kStart + 8 * kSweep), StampVerdict::kGap);
  EXPECT_EQ(check.check(kStart + 8 * kSweep + 50 * kMs), StampVerdict::kInSequence);
}

TEST(StampCheck, ResetStartsOverButKeepsTheCounts)
{
  StampCheck check(tenHertz());
  check.check(kStart);
  check.check(kStart);
  check.reset();
  EXPECT_EQ(check.check(kStart), StampVerdict::kFirst);  // no longer a duplicate
  EXPECT_EQ(check.check(kStart - 20 * kSweep), StampVerdict::kJumpedBack);
  check.reset();
  EXPECT_EQ(check.check(kStart - 30 * kSweep), StampVerdict::kFirst);  // nor a step back
  EXPECT_EQ(check.counts().duplicates, 1u);
  EXPECT_EQ(check.counts().jumps_back, 1u);
  EXPECT_EQ(check.counts().taken, 4u);
}

TEST(StampCheck, ZeroAndNegativeStampsAreOrderedLikeAnyOther)
{
  StampCheck check(tenHertz());
  EXPECT_EQ(check.check(0), StampVerdict::kFirst);
  EXPECT_EQ(check.check(0), StampVerdict::kDuplicate);
  EXPECT_EQ(check.check(kSweep), StampVerdict::kInSequence);
  EXPECT_EQ(check.check(-kSweep), StampVerdict::kOutOfOrder);
}

TEST(StampCheck, EveryVerdictHasItsOwnName)
{
  std::set<std::string> names;
  for (StampVerdict v : { StampVerdict::kFirst, StampVerdict::kInSequence, StampVerdict::kGap,
                          StampVerdict::kJumpedBack, StampVerdict::kDuplicate, StampVerdict::kOutOfOrder })
  {
    names.insert(toString(v));
  }
  EXPECT_EQ(names.size(), 6u);
  EXPECT_EQ(std::string(toString(StampVerdict::kDuplicate)), "duplicate");
}

}  // namespace
}  // namespace aloam
