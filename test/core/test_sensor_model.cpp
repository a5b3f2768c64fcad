// Tests of SensorModel: presets, ring assignment from elevation, table construction.
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "aloam_nodelet/core/sensor_model.h"

namespace aloam
{
namespace
{
constexpr double kDegToRad = M_PI / 180.0;
// Fraction of the half-gap to a neighbouring beam that must still map to the beam itself.
constexpr double kInsideFraction = 0.4;
// Fraction of the outer half-gap beyond which an elevation belongs to no beam.
constexpr double kOutsideFraction = 1.05;
constexpr double kTableTolerance = 1e-9;

int ringAtDeg(const SensorModel& model, double elevation_deg)
{
  return model.ringForElevation(elevation_deg * kDegToRad);
}

// Checks that every beam of `model` owns its elevation and +-40 % of the half-gaps around it, and that
// elevations past the outer half-gaps map to no ring.
void expectEveryBeamOwnsItsNeighbourhood(const SensorModel& model)
{
  const std::vector<double>& e = model.elevationsDeg();
  const int n = model.numRings();
  ASSERT_EQ(static_cast<int>(e.size()), n);
  ASSERT_GE(n, 2);
  for (int i = 0; i < n; ++i)
  {
    const std::size_t k = static_cast<std::size_t>(i);
    // The outermost beams use their only neighbour's gap on the open side too.
    const double half_gap_below = 0.5 * (i > 0 ? e[k] - e[k - 1] : e[1] - e[0]);
    const double half_gap_above = 0.5 * (i + 1 < n ? e[k + 1] - e[k] : e[k] - e[k - 1]);
    EXPECT_EQ(ringAtDeg(model, e[k]), i) << model.name() << " beam " << i;
    EXPECT_EQ(ringAtDeg(model, e[k] - kInsideFraction * half_gap_below), i) << model.name() << " beam " << i;
    EXPECT_EQ(ringAtDeg(model, e[k] + kInsideFraction * half_gap_above), i) << model.name() << " beam " << i;
  }
  const double outer_low = 0.5 * (e[1] - e[0]);
  const double outer_high = 0.5 * (e[static_cast<std::size_t>(n - 1)] - e[static_cast<std::size_t>(n - 2)]);
  EXPECT_EQ(ringAtDeg(model, e.front() - kOutsideFraction * outer_low), -1) << model.name();
  EXPECT_EQ(ringAtDeg(model, e.back() + kOutsideFraction * outer_high), -1) << model.name();
  EXPECT_EQ(ringAtDeg(model, -90.0), -1) << model.name();
  EXPECT_EQ(ringAtDeg(model, 90.0), -1) << model.name();
}
}  // namespace

// Every preset exists, has a strictly ascending table, and each beam owns +-40 % of its half-gaps.
TEST(SensorModelTest, EveryPresetAssignsEveryBeamToItsRing)
{
  const std::vector<std::string> names = SensorModel::presetNames();
  const std::set<std::string> expected = { "VLP16", "HDL32", "HDL64", "VLP32C", "OS1_64", "OS0_64", "OS1_128" };
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()), expected);
  for (const std::string& name : names)
  {
    const std::optional<SensorModel> model = SensorModel::fromPreset(name);
    ASSERT_TRUE(model.has_value()) << name;
    EXPECT_EQ(model->name(), name);
    EXPECT_GT(model->columns(), 0) << name;
    EXPECT_GT(model->scanPeriod(), 0.0) << name;
    const std::vector<double>& e = model->elevationsDeg();
    for (std::size_t i = 1; i < e.size(); ++i)
    {
      EXPECT_LT(e[i - 1], e[i]) << name << " beam " << i;
    }
    expectEveryBeamOwnsItsNeighbourhood(*model);
  }
}

// Presets carry the beam count of the real sensors.
TEST(SensorModelTest, PresetBeamCounts)
{
  EXPECT_EQ(SensorModel::fromPreset("VLP16")->numRings(), 16);
  EXPECT_EQ(SensorModel::fromPreset("HDL32")->numRings(), 32);
  EXPECT_EQ(SensorModel::fromPreset("HDL64")->numRings(), 64);
  EXPECT_EQ(SensorModel::fromPreset("VLP32C")->numRings(), 32);
  EXPECT_EQ(SensorModel::fromPreset("OS1_64")->numRings(), 64);
  EXPECT_EQ(SensorModel::fromPreset("OS0_64")->numRings(), 64);
  EXPECT_EQ(SensorModel::fromPreset("OS1_128")->numRings(), 128);
}

// Driver ring fields: Velodyne counts from the lowest beam (passed through), ouster_ros from the highest
// (flipped into the model's bottom-up rings; values past the table fit no ring).
TEST(SensorModelTest, RingFieldOrderFollowsTheDriver)
{
  for (const std::string name : { "VLP16", "HDL32", "HDL64", "VLP32C" })
  {
    const SensorModel model = *SensorModel::fromPreset(name);
    EXPECT_FALSE(model.ringFieldFromTop()) << name;
    EXPECT_EQ(model.ringFromField(0), 0) << name;
    EXPECT_EQ(model.ringFromField(model.numRings() - 1), model.numRings() - 1) << name;
  }
  for (const std::string name : { "OS1_64", "OS0_64", "OS1_128" })
  {
    const SensorModel model = *SensorModel::fromPreset(name);
    const int top = model.numRings() - 1;
    EXPECT_TRUE(model.ringFieldFromTop()) << name;
    EXPECT_EQ(model.ringFromField(0), top) << name;
    EXPECT_EQ(model.ringFromField(top), 0) << name;
    EXPECT_EQ(model.ringFromField(20), top - 20) << name;
    EXPECT_EQ(model.ringFromField(top + 1), -1) << name;
  }
  EXPECT_FALSE(SensorModel::uniform(64, -22.5, 22.5).ringFieldFromTop());
}

// HDL64: the 64 beams map to 64 distinct rings 0..63, including 51-63 that A-LOAM's formula drops.
TEST(SensorModelTest, Hdl64UsesAllSixtyFourRings)
{
  const SensorModel model = *SensorModel::fromPreset("HDL64");
  std::set<int> rings;
  for (const double e : model.elevationsDeg())
  {
    rings.insert(ringAtDeg(model, e));
  }
  EXPECT_EQ(rings.size(), 64u);
  EXPECT_EQ(*rings.begin(), 0);
  EXPECT_EQ(*rings.rbegin(), 63);
  // The lowest beams are the ones A-LOAM loses (it only keeps rings 0..50 counted from the top).
  constexpr int kFirstRingDroppedByAloam = 51;
  int high_rings = 0;
  for (const int r : rings)
  {
    high_rings += r >= kFirstRingDroppedByAloam ? 1 : 0;
  }
  EXPECT_EQ(high_rings, 64 - kFirstRingDroppedByAloam);
}

// uniform(n, lo, hi): evenly spaced inclusive table, bounds in any order, one beam allowed, n < 1 throws.
TEST(SensorModelTest, UniformTable)
{
  constexpr int kBeams = 9;
  constexpr double kLow = -20.0;
  constexpr double kHigh = 12.0;
  const SensorModel model = SensorModel::uniform(kBeams, kLow, kHigh);
  ASSERT_EQ(model.numRings(), kBeams);
  const double step = (kHigh - kLow) / (kBeams - 1);
  for (int i = 0; i < kBeams; ++i)
  {
    EXPECT_NEAR(model.elevationsDeg()[static_cast<std::size_t>(i)], kLow + step * i, kTableTolerance);
  }
  const SensorModel swapped = SensorModel::uniform(kBeams, kHigh, kLow);
  EXPECT_EQ(swapped.elevationsDeg(), model.elevationsDeg());

  const SensorModel single = SensorModel::uniform(1, 3.0, 3.0);
  ASSERT_EQ(single.numRings(), 1);
  EXPECT_EQ(ringAtDeg(single, 3.0), 0);
  EXPECT_EQ(ringAtDeg(single, 3.5), 0);
  EXPECT_EQ(ringAtDeg(single, 10.0), -1);

  EXPECT_THROW(SensorModel::uniform(0, -1.0, 1.0), std::invalid_argument);
  EXPECT_THROW(SensorModel::uniform(-3, -1.0, 1.0), std::invalid_argument);
}

// fromTable sorts its input, drops non-finite entries and throws when nothing is left.
TEST(SensorModelTest, FromTableSortsAndDropsNonFinite)
{
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const SensorModel model = SensorModel::fromTable({ 4.0, -10.0, nan, 1.0, -2.5, inf });
  const std::vector<double> expected = { -10.0, -2.5, 1.0, 4.0 };
  EXPECT_EQ(model.elevationsDeg(), expected);
  EXPECT_EQ(model.numRings(), 4);
  // Ring indices follow the sorted order, not the input order.
  EXPECT_EQ(ringAtDeg(model, -10.0), 0);
  EXPECT_EQ(ringAtDeg(model, -2.5), 1);
  EXPECT_EQ(ringAtDeg(model, 1.0), 2);
  EXPECT_EQ(ringAtDeg(model, 4.0), 3);
  expectEveryBeamOwnsItsNeighbourhood(model);

  EXPECT_THROW(SensorModel::fromTable({}), std::invalid_argument);
  EXPECT_THROW(SensorModel::fromTable({ nan, nan }), std::invalid_argument);
}

// Unknown or differently cased preset names give nullopt; a non-finite elevation gives no ring.
TEST(SensorModelTest, UnknownPresetAndNonFiniteElevation)
{
  EXPECT_FALSE(SensorModel::fromPreset("vlp16").has_value());
  EXPECT_FALSE(SensorModel::fromPreset("HDL-64").has_value());
  EXPECT_FALSE(SensorModel::fromPreset("").has_value());
  const SensorModel model = *SensorModel::fromPreset("VLP16");
  EXPECT_EQ(model.ringForElevation(std::numeric_limits<double>::quiet_NaN()), -1);
  EXPECT_EQ(model.ringForElevation(std::numeric_limits<double>::infinity()), -1);
  EXPECT_EQ(model.ringForElevation(-std::numeric_limits<double>::infinity()), -1);
}

// A 32-beam table rounds to the nearest beam; A-LOAM's HDL-32 formula truncates and files an
// elevation just below a beam under the beam beneath it.
TEST(SensorModelTest, ThirtyTwoBeamTableRoundsToNearestBeam)
{
  const SensorModel model = *SensorModel::fromPreset("HDL32");
  const std::vector<double>& e = model.elevationsDeg();
  ASSERT_EQ(e.size(), 32u);
  // A-LOAM: scanID = int((angle + 92 / 3) * 3 / 4) for 32 beams.
  const auto aloam_ring = [](double angle_deg) { return static_cast<int>((angle_deg + 92.0 / 3.0) * 3.0 / 4.0); };
  const double spacing = e[1] - e[0];
  constexpr double kBelowFraction = 0.3;  // of the beam spacing, i.e. 60 % of the half-gap
  int truncation_disagreements = 0;
  for (int i = 1; i < 32; ++i)
  {
    const double below = e[static_cast<std::size_t>(i)] - kBelowFraction * spacing;
    EXPECT_EQ(ringAtDeg(model, below), i) << "beam " << i;
    truncation_disagreements += aloam_ring(below) != i ? 1 : 0;
  }
  // The truncating formula gets every one of these wrong; the model gets none wrong.
  EXPECT_EQ(truncation_disagreements, 31);

  // Same with an arbitrary (non-uniform, widening) 32-beam table.
  constexpr double kLowestDeg = -25.0, kSpacingDeg = 1.1, kWideningDeg = 0.02;
  constexpr double kNearer = 0.45, kFarther = 0.55;  // fractions of the gap to a neighbour
  std::vector<double> table;
  for (int i = 0; i < 32; ++i)
  {
    table.push_back(kLowestDeg + kSpacingDeg * i + kWideningDeg * i * i);
  }
  const SensorModel custom = SensorModel::fromTable(table);
  for (int i = 1; i + 1 < 32; ++i)
  {
    const std::size_t k = static_cast<std::size_t>(i);
    const double gap_below = table[k] - table[k - 1];
    const double gap_above = table[k + 1] - table[k];
    // 45 % of a gap away is still nearer to this beam; 55 % is nearer to the neighbour.
    EXPECT_EQ(ringAtDeg(custom, table[k] - kNearer * gap_below), i);
    EXPECT_EQ(ringAtDeg(custom, table[k] + kNearer * gap_above), i);
    EXPECT_EQ(ringAtDeg(custom, table[k] - kFarther * gap_below), i - 1);
    EXPECT_EQ(ringAtDeg(custom, table[k] + kFarther * gap_above), i + 1);
  }
}

}  // namespace aloam

namespace aloam
{
namespace
{
// The registration's ring lookup without an arctangent files every point as the elevation lookup does,
// also points just beside the ring bounds and outside the table.
TEST(SensorModelTest, RingForPointAgreesWithRingForElevation)
{
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> azimuth(-M_PI, M_PI);
  std::uniform_real_distribution<double> range(0.5, 150.0);
  std::uniform_real_distribution<double> jitter(-1e-6, 1e-6);
  for (const std::string& name : SensorModel::presetNames())
  {
    const SensorModel model = *SensorModel::fromPreset(name);
    std::vector<double> elevations_deg;
    const std::vector<double>& e = model.elevationsDeg();
    for (std::size_t i = 0; i < e.size(); ++i)
    {
      elevations_deg.push_back(e[i]);
      if (i + 1 < e.size())
      {
        elevations_deg.push_back(0.5 * (e[i] + e[i + 1]));  // a bound, give or take the jitter
      }
    }
    std::uniform_real_distribution<double> any(e.front() - 10.0, e.back() + 10.0);
    for (int k = 0; k < 20000; ++k)
    {
      elevations_deg.push_back(any(rng));
    }
    int mismatched = 0, assigned = 0;
    for (const double elevation_deg : elevations_deg)
    {
      const double el = (elevation_deg + jitter(rng)) * M_PI / 180.0;
      const double a = azimuth(rng), r = range(rng);
      const double x = r * std::cos(el) * std::cos(a), y = r * std::cos(el) * std::sin(a), z = r * std::sin(el);
      const int expected = model.ringForElevation(std::atan2(z, std::sqrt(x * x + y * y)));
      mismatched += model.ringForPoint(x, y, z) != expected ? 1 : 0;
      assigned += expected >= 0 ? 1 : 0;
    }
    EXPECT_EQ(mismatched, 0) << name;
    EXPECT_GT(assigned, 1000) << name;
    EXPECT_EQ(model.ringForPoint(0.0, 0.0, 0.0), -1) << name;
    EXPECT_EQ(model.ringForPoint(0.0, 0.0, 5.0), -1) << name;   // straight up
    EXPECT_EQ(model.ringForPoint(0.0, 0.0, -5.0), -1) << name;  // straight down
    EXPECT_EQ(model.ringForPoint(std::numeric_limits<double>::quiet_NaN(), 1.0, 0.0), -1) << name;
  }
}

}  // namespace
}  // namespace aloam
